//! `igi-fuzz TARGET|all [--runs N] [--seed S] [--work DIR] [--crashes DIR] [--fixtures DIR]`:
//! fuzz parsers for a fixed number of executions and print one line of counts per target.
//! Exit status 1 when any target crashed, hung (> 1 s) or went over 2 GiB of heap.

use igi_fuzz::{fuzz, target, targets, Config, CountingAlloc};
use std::path::PathBuf;

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let Some(which) = args.first().cloned() else {
        eprintln!("usage: igi-fuzz TARGET|all [--runs N] [--seed S] [--work DIR] [--crashes DIR] [--fixtures DIR]");
        std::process::exit(2);
    };
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let cfg = Config {
        executions: value("--runs").map_or(10_000, |v| v.parse().expect("--runs takes a number")),
        seed: value("--seed").map_or(1, |v| v.parse().expect("--seed takes a number")),
        fixtures: value("--fixtures").map_or(root.join("datasets/fixtures"), PathBuf::from),
        work: value("--work").map_or(std::env::temp_dir().join("igi-fuzz"), PathBuf::from),
        crashes: value("--crashes")
            .map_or(std::env::temp_dir().join("igi-fuzz-crashes"), PathBuf::from),
        time_limit_ms: 1000.0,
        memory_limit: 2 << 30,
    };
    let list = if which == "all" {
        targets()
    } else {
        match target(&which) {
            Ok(t) => vec![t],
            Err(e) => {
                eprintln!("error: {e}");
                std::process::exit(2);
            }
        }
    };
    let mut failed = false;
    println!("target,executions,accepted,errors,crashes,hangs,over_memory,slowest_ms,peak_MiB,corpus,wall_s");
    for t in &list {
        match fuzz(t, &cfg) {
            Ok(s) => {
                failed |= s.crashes + s.hangs + s.over_memory > 0;
                println!(
                    "{},{},{},{},{},{},{},{:.1},{:.1},{},{:.1}",
                    s.target,
                    s.executions,
                    s.accepted,
                    s.errors,
                    s.crashes,
                    s.hangs,
                    s.over_memory,
                    s.slowest_ms,
                    s.peak_bytes as f64 / (1 << 20) as f64,
                    s.corpus,
                    s.wall_s
                );
            }
            Err(e) => {
                eprintln!("error: {e}");
                failed = true;
            }
        }
    }
    if failed {
        std::process::exit(1);
    }
}
