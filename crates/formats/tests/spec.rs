//! `docs/FORMATS.md` honours the interchange contract `../shared/FORMATS.md` line for line, and
//! the examples igi's own docs give parse with the `igi-formats` types.

use std::path::PathBuf;

fn repo() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

#[test]
fn every_line_of_the_shared_contract_is_in_docs_formats() {
    let shared = repo().join("../shared/FORMATS.md");
    let contract = std::fs::read_to_string(&shared).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (the interchange contract lives in ../shared beside the checkout)",
            shared.display()
        )
    });
    let ours = std::fs::read_to_string(repo().join("docs/FORMATS.md")).unwrap();
    let lines: Vec<&str> = ours.lines().collect();
    let missing: Vec<&str> = contract
        .lines()
        .filter(|l| !l.trim().is_empty() && !lines.contains(l))
        .collect();
    assert!(
        contract.lines().count() > 100,
        "the contract is shorter than expected"
    );
    assert!(
        missing.is_empty(),
        "docs/FORMATS.md lacks these lines of ../shared/FORMATS.md: {missing:#?}"
    );
    // the contract is copied in order, as one block
    assert!(
        ours.contains(contract.trim()),
        "the contract is not one verbatim block"
    );
}

#[test]
fn the_extension_examples_of_docs_formats_parse() {
    let ours = std::fs::read_to_string(repo().join("docs/FORMATS.md")).unwrap();
    let part2 = &ours[ours.find("# Part 2").expect("a Part 2")..];
    let start = part2.find("```toml\n[site]").expect("the survey example") + 8;
    let block = &part2[start..start + part2[start..].find("```").unwrap()];
    let f: igi_formats::SurveyFile = toml::from_str(block).unwrap();
    assert_eq!(f.site.prepared.as_deref(), Some("site.igi".as_ref()));
    let p = &f.photo[0];
    assert_eq!(
        p.probe.as_ref().unwrap().board,
        PathBuf::from("probes/board.json")
    );
    assert_eq!(
        p.radiometry.as_deref(),
        Some("calibration/other.json".as_ref())
    );
    assert!(p.lighting.is_none());
}
