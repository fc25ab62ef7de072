//! Conventions several crates share: the Rec. 709 luminance of linear RGB, the median of a
//! sample, and FORMATS.md's default angular diameter of the sun.

/// The sun's angular diameter when a lighting file gives none (FORMATS.md), degrees.
pub const SUN_ANGULAR_DIAMETER_DEG: f64 = 0.53;

/// Rec. 709 luminance of linear RGB.
#[inline]
pub fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Rec. 709 luminance of linear RGB in double precision.
#[inline]
pub fn luminance_f64(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The median of `v` (the upper one of an even count), sorting `v`; 0 for an empty slice.
pub fn median_in_place(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn luminance_weights_sum_to_one_and_the_median_is_the_middle() {
        assert!((luminance([1.0; 3]) - 1.0).abs() < 1e-6);
        assert!((luminance_f64([1.0; 3]) - 1.0).abs() < 1e-12);
        assert_eq!(luminance_f64([0.0, 1.0, 0.0]), 0.7152);
        assert_eq!(median_in_place(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median_in_place(&mut [4.0, 1.0, 3.0, 2.0]), 3.0);
        assert_eq!(median_in_place(&mut []), 0.0);
        assert_eq!(median_in_place(&mut [f64::NAN, 1.0, 2.0]), 2.0);
    }
}
