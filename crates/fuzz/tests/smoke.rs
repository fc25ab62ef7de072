//! A CI-sized fuzz run: every target, a few hundred executions, no crash, hang or blow-up.
//! (The million-execution runs are `scripts/fuzz.sh`; counts in docs/RELIABILITY.md.)

use igi_fuzz::{fuzz, targets, Config, CountingAlloc};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

#[test]
fn every_parser_survives_a_short_fuzz_run() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = Config {
        executions: 300,
        seed: 7,
        fixtures: igi_testkit::fixture(""),
        work: tmp.path().join("work"),
        crashes: tmp.path().join("crashes"),
        time_limit_ms: 1000.0,
        memory_limit: 2 << 30,
    };
    for t in targets() {
        let s = fuzz(&t, &cfg).unwrap();
        assert_eq!(s.executions, 300);
        assert_eq!((s.crashes, s.hangs, s.over_memory), (0, 0, 0), "{s:?}");
        // the seeds parse, and mutations find errors
        assert!(s.accepted > 0 && s.errors > 0, "{s:?}");
    }
}
