//! clap value parsers for numbers that must mean something (issue 36 item 7): clap names the
//! option in its error (`invalid value '-1' for '--threshold <THRESHOLD>': ...`), before any
//! work.

fn number(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number"))?;
    if v.is_nan() {
        return Err("NaN is not a value".into());
    }
    Ok(v)
}

/// A finite number above 0 (a size, a length, a threshold, a memory limit).
pub fn positive(s: &str) -> Result<f64, String> {
    match number(s)? {
        v if v.is_finite() && v > 0.0 => Ok(v),
        v => Err(format!("{v} must be a finite number above 0")),
    }
}

/// A finite number of at least 0 (a weight, a tolerance, a mask radius).
pub fn non_negative(s: &str) -> Result<f64, String> {
    match number(s)? {
        v if v.is_finite() && v >= 0.0 => Ok(v),
        v => Err(format!("{v} must be a finite number of at least 0")),
    }
}

/// [`non_negative`] as f32.
pub fn non_negative_f32(s: &str) -> Result<f32, String> {
    non_negative(s).map(|v| v as f32)
}

/// [`positive`] as f32.
pub fn positive_f32(s: &str) -> Result<f32, String> {
    positive(s).map(|v| v as f32)
}

/// A fraction in 0..=1 (an albedo channel, a pixel value).
pub fn unit_f32(s: &str) -> Result<f32, String> {
    match number(s)? {
        v if (0.0..=1.0).contains(&v) => Ok(v as f32),
        v => Err(format!("{v} must be in [0, 1]")),
    }
}

/// A fraction above 0 and at most 1 (a share to keep).
pub fn share(s: &str) -> Result<f64, String> {
    match number(s)? {
        v if v > 0.0 && v <= 1.0 => Ok(v),
        v => Err(format!("{v} must be above 0 and at most 1")),
    }
}

/// An angle from the normal in degrees, above 0 and at most 90.
pub fn incidence_deg(s: &str) -> Result<f64, String> {
    match number(s)? {
        v if v > 0.0 && v <= 90.0 => Ok(v),
        v => Err(format!(
            "{v} degrees must be above 0 and at most 90 (an angle from the normal)"
        )),
    }
}

/// A cone's half angle in degrees, 0 to 180.
pub fn cone_deg(s: &str) -> Result<f64, String> {
    match number(s)? {
        v if (0.0..=180.0).contains(&v) => Ok(v),
        v => Err(format!("{v} degrees must be in [0, 180]")),
    }
}

/// A hull's carving cells per axis of the bounding box: at least 256.
pub fn hull_resolution(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(v) if v >= 256 => Ok(v),
        Ok(v) => Err(format!(
            "{v} must be at least 256 (cells per axis of the bounding box)"
        )),
        Err(_) => Err(format!("{s:?} is not a whole number")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nonsense_numbers_are_refused() {
        for bad in ["-1", "0", "nan", "NaN", "inf", "-inf", "x", ""] {
            assert!(positive(bad).is_err(), "{bad}");
        }
        assert_eq!(positive("1e-3"), Ok(1e-3));
        assert!(non_negative("-0.5").is_err() && non_negative("nan").is_err());
        assert_eq!(non_negative("0"), Ok(0.0));
        assert!(unit_f32("5").is_err() && unit_f32("-0.1").is_err());
        assert!(share("0").is_err() && share("1.5").is_err() && share("1").is_ok());
        assert!(incidence_deg("200").is_err() && incidence_deg("0").is_err());
        assert!(cone_deg("-1").is_err() && cone_deg("181").is_err());
        assert!(hull_resolution("255").is_err() && hull_resolution("-256").is_err());
        assert_eq!(hull_resolution("256"), Ok(256));
    }
}
