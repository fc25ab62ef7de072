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

/// The contract's "Site location and photo time" example: the `toml` block holding
/// `latitude_deg = 37.9715`.
fn site_location_example(doc: &str) -> &str {
    let at = doc
        .find("\nlatitude_deg = 37.9715")
        .expect("the site location example");
    let start = doc[..at].rfind("```toml\n").expect("its opening fence") + "```toml\n".len();
    let end = at + doc[at..].find("```").expect("its closing fence");
    &doc[start..end]
}

#[test]
fn the_site_location_and_photo_time_example_parses_and_checks() {
    let ours = std::fs::read_to_string(repo().join("docs/FORMATS.md")).unwrap();
    let block = site_location_example(&ours);
    assert!(block.starts_with("[site]\n"), "{block}");
    let f: igi_formats::SurveyFile = toml::from_str(block).unwrap();
    assert_eq!(f.site.mesh.as_deref(), Some("geometry/site.ply".as_ref()));
    assert_eq!(f.site.latitude_deg, Some(37.9715));
    assert_eq!(f.site.longitude_deg, Some(23.7267));
    assert_eq!(f.site.north, Some([0.0, 1.0, 0.0]));
    assert_eq!(f.photo.len(), 1);
    let p = &f.photo[0];
    assert_eq!(p.id, "east-0930");
    assert!(p.lighting.is_none() && p.probe.is_none());
    assert_eq!(p.time.as_deref(), Some("2026-06-21T09:30:00+03:00"));
    let t = p.photo_time().unwrap().unwrap();
    // `date -u -d 2026-06-21T06:30:00Z +%s`
    assert_eq!(t.unix_seconds(), 1_782_023_400);
    assert_eq!(t.nanos(), 0);
    assert_eq!(t.offset_seconds(), 3 * 3600);
    assert_eq!(t.to_rfc3339_utc(), "2026-06-21T06:30:00Z");
    let u = t.utc();
    assert_eq!(
        (u.year, u.month, u.day, u.hour, u.minute),
        (2026, 6, 21, 6, 30)
    );
    assert_eq!(u.second, 0.0);
    assert!(f.reference.is_empty());
    f.check_site_and_references(std::path::Path::new("survey.toml"))
        .unwrap();
}
