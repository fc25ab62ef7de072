//! The BRDF sample CSV (FORMATS.md) and the direction-pair table: the file models and their
//! reader and writer live in `igi-formats` ([`igi_formats::brdf_samples`], re-exported here);
//! this module adds what the fit does with them.

pub use igi_formats::brdf_samples::{
    pairs_to_csv, parse_samples, read_pairs, read_samples, samples_to_csv, write_pairs,
    write_samples, BrdfSample, PairRow, PairTable, SampleProblem, MAX_BRDF,
};

/// Group samples by material, in order of first appearance.
pub fn group_by_material(samples: &[BrdfSample]) -> Vec<(String, Vec<BrdfSample>)> {
    let mut groups: Vec<(String, Vec<BrdfSample>)> = Vec::new();
    for s in samples {
        match groups.iter_mut().find(|(m, _)| *m == s.material) {
            Some((_, g)) => g.push(s.clone()),
            None => groups.push((s.material.clone(), vec![s.clone()])),
        }
    }
    groups
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use std::path::Path;

    #[test]
    fn groups_in_order_of_first_appearance() {
        let text = "material,light_x,light_y,light_z,view_x,view_y,view_z,r,g,b\n\
                    white,0,0,1,0.6,0,0.8,1,1,1\n\
                    dark,0.6,0,0.8,0,0,1,0.01,0.02,0.03\n\
                    white,0,0,1,0,0,1,1,1,1\n";
        let s = parse_samples(text, Path::new("x.csv")).unwrap();
        let g = group_by_material(&s);
        assert_eq!(g.len(), 2);
        assert_eq!((g[0].0.as_str(), g[0].1.len()), ("white", 2));
        assert_eq!(g[1].1[0].value, Vec3::new(0.01, 0.02, 0.03));
    }
}
