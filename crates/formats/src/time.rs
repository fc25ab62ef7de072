//! When a photo was taken (`docs/FORMATS.md`, "Site location and photo time"): an instant on the
//! UTC time line with the UTC offset it was written with.
//!
//! A survey's `[[photo]] time` is RFC 3339 with its offset (`2026-06-21T09:30:00+03:00`,
//! `...Z`); [`PhotoTime::parse_rfc3339`] reads it and refuses a local time without an offset,
//! which does not fix the instant (and so not the sun). [`PhotoTime::from_exif`] reads EXIF's
//! `DateTimeOriginal` (`YYYY:MM:DD HH:MM:SS`) with its `OffsetTimeOriginal` (`+HH:MM`).
//! [`PhotoTime::utc`] gives the UTC calendar date and time of day (proleptic Gregorian), what a
//! solar-position algorithm takes.
//!
//! Hand-written: dates are converted with the days-from-civil algorithm (H. Hinnant,
//! "chrono-Compatible Low-Level Date Algorithms"), exact for every year 0000..=9999. A leap
//! second (`:60`) is read as `:59` of the same minute (one second is nothing to the sun).

use std::fmt;

/// The largest UTC offset accepted, in seconds (±18:00, as ISO 8601 and most libraries bound it).
pub const MAX_OFFSET_SECONDS: i32 = 18 * 3600;

/// A photograph's clock and GPS stamp this far apart or further are noted
/// ([`PhotoTime::exif_clock_gps_note`]): the sun moves 2.5 degrees in 10 minutes.
pub const CLOCK_GPS_NOTE_S: i64 = 600;

/// An instant (UTC seconds since 1970-01-01T00:00:00Z plus nanoseconds) and the UTC offset it
/// was written with. Two values are equal when both the instant and the offset are; compare
/// [`PhotoTime::unix_seconds`] and [`PhotoTime::nanos`] for the instant alone.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PhotoTime {
    unix_seconds: i64,
    nanos: u32,
    offset_seconds: i32,
}

/// The UTC calendar date and time of day of a [`PhotoTime`] (proleptic Gregorian calendar).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UtcDateTime {
    pub year: i32,
    /// 1..=12
    pub month: u32,
    /// 1..=31
    pub day: u32,
    /// 0..=23
    pub hour: u32,
    /// 0..=59
    pub minute: u32,
    /// Seconds into the minute with their fraction, in [0, 60).
    pub second: f64,
}

/// Why a time cannot be read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TimeProblem {
    /// A date and time without a UTC offset: it names no instant.
    #[error(
        "the UTC offset is missing (end the time with `Z` for UTC or an offset such as `+03:00`): \
         a local time alone does not say when the photo was taken"
    )]
    MissingOffset,
    /// An EXIF time whose `OffsetTimeOriginal` is absent.
    #[error(
        "the UTC offset is unknown (the EXIF data has no OffsetTimeOriginal): a local time alone \
         does not say when the photo was taken; give the photo a `time` with its offset"
    )]
    UnknownOffset,
    /// The text is not laid out as the format says.
    #[error("not {format}: expected {expected} at character {at}")]
    Syntax {
        format: &'static str,
        expected: &'static str,
        /// 1-based character position.
        at: usize,
    },
    /// A field beyond its range (month 13, hour 24, ...).
    #[error("{field} {value} is out of range {min}..={max}")]
    Field {
        field: &'static str,
        value: u32,
        min: u32,
        max: u32,
    },
    /// A day that its month does not have (February 30).
    #[error("{year:04}-{month:02} has {days} days, not {day}")]
    Day {
        year: i32,
        month: u32,
        day: u32,
        days: u32,
    },
    /// A UTC offset beyond ±18:00 (or with minutes past 59).
    #[error("UTC offset {0} is beyond ±18:00")]
    Offset(String),
    /// An EXIF date left blank by the camera (`    :  :     :  :  `).
    #[error("the EXIF date and time are blank (the camera did not know them)")]
    Blank,
    /// EXIF data without `DateTimeOriginal` and without a GPS date and time.
    #[error(
        "the EXIF data holds no DateTimeOriginal and no GPS date and time; give the photo a `time`"
    )]
    NoExifTime,
}

const RFC3339: &str = "an RFC 3339 time (YYYY-MM-DDTHH:MM:SS[.fraction] then Z or +HH:MM)";
const EXIF: &str = "an EXIF time (YYYY:MM:DD HH:MM:SS)";
const EXIF_OFFSET: &str = "an EXIF UTC offset (+HH:MM)";

/// A cursor over ASCII text that reads fixed-width fields.
struct Cursor<'a> {
    s: &'a [u8],
    i: usize,
    format: &'static str,
}

impl<'a> Cursor<'a> {
    fn new(s: &'a str, format: &'static str) -> Self {
        Cursor {
            s: s.as_bytes(),
            i: 0,
            format,
        }
    }

    fn error(&self, expected: &'static str) -> TimeProblem {
        TimeProblem::Syntax {
            format: self.format,
            expected,
            at: self.i + 1,
        }
    }

    fn peek(&self) -> Option<u8> {
        self.s.get(self.i).copied()
    }

    fn at_end(&self) -> bool {
        self.i >= self.s.len()
    }

    /// Exactly `n` decimal digits as a number.
    fn digits(&mut self, n: usize, expected: &'static str) -> Result<u32, TimeProblem> {
        let mut v = 0u32;
        for _ in 0..n {
            match self.peek() {
                Some(c) if c.is_ascii_digit() => {
                    v = v * 10 + u32::from(c - b'0');
                    self.i += 1;
                }
                _ => return Err(self.error(expected)),
            }
        }
        Ok(v)
    }

    /// One byte out of `set`.
    fn one_of(&mut self, set: &[u8], expected: &'static str) -> Result<u8, TimeProblem> {
        match self.peek() {
            Some(c) if set.contains(&c) => {
                self.i += 1;
                Ok(c)
            }
            _ => Err(self.error(expected)),
        }
    }

    /// Optional `.` and at least one digit: the fraction of a second, truncated to nanoseconds.
    fn fraction(&mut self) -> Result<u32, TimeProblem> {
        if self.peek() != Some(b'.') {
            return Ok(0);
        }
        self.i += 1;
        let start = self.i;
        let mut nanos = 0u32;
        while let Some(c) = self.peek().filter(u8::is_ascii_digit) {
            if self.i - start < 9 {
                nanos = nanos * 10 + u32::from(c - b'0');
            }
            self.i += 1;
        }
        let n = self.i - start;
        if n == 0 {
            return Err(self.error("digits after `.`"));
        }
        for _ in n..9 {
            nanos *= 10;
        }
        Ok(nanos)
    }

    /// `+HH:MM` or `-HH:MM` as seconds east of UTC, at most ±18:00.
    fn numeric_offset(&mut self) -> Result<i32, TimeProblem> {
        let start = self.i;
        let sign = self.one_of(b"+-", "`+` or `-` starting the UTC offset")?;
        let h = self.digits(2, "two-digit offset hours")?;
        self.one_of(b":", "`:` in the UTC offset")?;
        let m = self.digits(2, "two-digit offset minutes")?;
        let secs = (h * 3600 + m * 60) as i32;
        if m > 59 || secs > MAX_OFFSET_SECONDS {
            let text = String::from_utf8_lossy(&self.s[start..self.i]).into_owned();
            return Err(TimeProblem::Offset(text));
        }
        Ok(if sign == b'-' { -secs } else { secs })
    }
}

/// A local calendar date and time of day, checked field by field.
struct Civil {
    year: i32,
    month: u32,
    day: u32,
    hour: u32,
    minute: u32,
    second: u32,
}

impl Civil {
    /// Reads `YYYY<ds>MM<ds>DD<sep>HH:MM:SS` (`ds` the date separator, `sep` one of `seps`).
    fn read(c: &mut Cursor, ds: u8, seps: &[u8]) -> Result<Civil, TimeProblem> {
        let year = c.digits(4, "a four-digit year")? as i32;
        c.one_of(&[ds], "the date separator")?;
        let month = c.digits(2, "a two-digit month")?;
        c.one_of(&[ds], "the date separator")?;
        let day = c.digits(2, "a two-digit day")?;
        c.one_of(seps, "`T` or a space between the date and the time")?;
        let hour = c.digits(2, "two-digit hours")?;
        c.one_of(b":", "`:` after the hours")?;
        let minute = c.digits(2, "two-digit minutes")?;
        c.one_of(b":", "`:` after the minutes")?;
        let second = c.digits(2, "two-digit seconds")?;
        let civil = Civil {
            year,
            month,
            day,
            hour,
            minute,
            second,
        };
        civil.check()?;
        Ok(civil)
    }

    fn check(&self) -> Result<(), TimeProblem> {
        let field = |field, value, min, max| {
            if (min..=max).contains(&value) {
                Ok(())
            } else {
                Err(TimeProblem::Field {
                    field,
                    value,
                    min,
                    max,
                })
            }
        };
        field("month", self.month, 1, 12)?;
        let days = days_in_month(self.year, self.month);
        if !(1..=days).contains(&self.day) {
            return Err(TimeProblem::Day {
                year: self.year,
                month: self.month,
                day: self.day,
                days,
            });
        }
        field("hour", self.hour, 0, 23)?;
        field("minute", self.minute, 0, 59)?;
        field("second", self.second, 0, 60)
    }

    /// Seconds since 1970-01-01T00:00:00 of this local time (a leap second read as `:59`).
    fn seconds(&self) -> i64 {
        let days = days_from_civil(self.year, self.month, self.day);
        let secs = self.hour * 3600 + self.minute * 60 + self.second.min(59);
        days * 86_400 + i64::from(secs)
    }
}

fn is_leap_year(y: i32) -> bool {
    (y % 4 == 0 && y % 100 != 0) || y % 400 == 0
}

/// Days in `month` (1..=12) of `year` (proleptic Gregorian).
pub fn days_in_month(year: i32, month: u32) -> u32 {
    match month {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        2 if is_leap_year(year) => 29,
        2 => 28,
        _ => 0,
    }
}

/// Days from 1970-01-01 to `year-month-day` (proleptic Gregorian; negative before 1970).
pub fn days_from_civil(year: i32, month: u32, day: u32) -> i64 {
    let y = i64::from(year) - i64::from(month <= 2);
    let era = y.div_euclid(400);
    let yoe = y - era * 400; // [0, 399]
    let mp = i64::from((month + 9) % 12); // March = 0
    let doy = (153 * mp + 2) / 5 + i64::from(day) - 1; // [0, 365]
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy; // [0, 146096]
    era * 146_097 + doe - 719_468
}

/// The date `days` after 1970-01-01: (year, month, day), the inverse of [`days_from_civil`].
pub fn civil_from_days(days: i64) -> (i32, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097; // [0, 146096]
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365; // [0, 399]
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100); // [0, 365]
    let mp = (5 * doy + 2) / 153; // [0, 11]
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year as i32, month, day)
}

impl PhotoTime {
    /// Reads an RFC 3339 time: `YYYY-MM-DDTHH:MM:SS`, optional `.fraction` (kept to the
    /// nanosecond), then `Z` or `+HH:MM` / `-HH:MM` (at most ±18:00). `T` may be a space, and
    /// `T`/`Z` lower case; surrounding whitespace is ignored. A time without an offset is
    /// refused ([`TimeProblem::MissingOffset`]).
    pub fn parse_rfc3339(text: &str) -> Result<PhotoTime, TimeProblem> {
        let mut c = Cursor::new(text.trim(), RFC3339);
        let civil = Civil::read(&mut c, b'-', b"Tt ")?;
        let nanos = c.fraction()?;
        let offset = match c.peek() {
            None => return Err(TimeProblem::MissingOffset),
            Some(b'Z' | b'z') => {
                c.i += 1;
                0
            }
            Some(_) => c.numeric_offset()?,
        };
        if !c.at_end() {
            return Err(c.error("the end of the time after its UTC offset"));
        }
        Ok(PhotoTime::from_local(&civil, nanos, offset))
    }

    /// Reads EXIF `DateTimeOriginal` (`YYYY:MM:DD HH:MM:SS`) with `OffsetTimeOriginal`
    /// (`+HH:MM`; `None` when the image has none: [`TimeProblem::UnknownOffset`]). Trailing
    /// NULs and spaces (EXIF pads its strings) are ignored; a blank date is
    /// [`TimeProblem::Blank`].
    pub fn from_exif(datetime: &str, offset: Option<&str>) -> Result<PhotoTime, TimeProblem> {
        let clean = |s: &str| {
            s.trim_matches(|c: char| c == '\0' || c.is_whitespace())
                .to_string()
        };
        let datetime = clean(datetime);
        if datetime.chars().all(|c| c == ':' || c == ' ') {
            return Err(TimeProblem::Blank);
        }
        let mut c = Cursor::new(&datetime, EXIF);
        let civil = Civil::read(&mut c, b':', b" ")?;
        if !c.at_end() {
            return Err(c.error("the end of the time after the seconds"));
        }
        let offset = offset.map(clean);
        let offset = match offset.as_deref() {
            None => return Err(TimeProblem::UnknownOffset),
            Some(o) if o.chars().all(|c| c == ':' || c == ' ') => {
                return Err(TimeProblem::UnknownOffset)
            }
            Some(o) => {
                let mut c = Cursor::new(o, EXIF_OFFSET);
                let secs = c.numeric_offset()?;
                if !c.at_end() {
                    return Err(c.error("the end of the offset after its minutes"));
                }
                secs
            }
        };
        Ok(PhotoTime::from_local(&civil, 0, offset))
    }

    /// When a photograph was taken, from its EXIF (`igi_imaging::exif::read_exif`):
    /// `DateTimeOriginal` with `OffsetTimeOriginal`, else the GPS date and time (UTC, so the
    /// instant keeps offset 0). A `DateTimeOriginal` without its offset and without a GPS time
    /// is [`TimeProblem::UnknownOffset`]; neither is [`TimeProblem::NoExifTime`].
    pub fn from_photo_exif(exif: &igi_imaging::exif::PhotoExif) -> Result<PhotoTime, TimeProblem> {
        match (
            &exif.date_time_original,
            &exif.offset_time_original,
            &exif.gps_utc,
        ) {
            (Some(local), Some(offset), _) => PhotoTime::from_exif(local, Some(offset)),
            (_, _, Some(utc)) => PhotoTime::from_exif(utc, Some("+00:00")),
            (Some(local), None, None) => PhotoTime::from_exif(local, None),
            (None, _, None) => Err(TimeProblem::NoExifTime),
        }
    }

    /// How far a photograph's clock (`DateTimeOriginal` at `OffsetTimeOriginal`) runs ahead
    /// of its GPS stamp, in seconds (negative: behind); `None` unless both are there and
    /// readable. An hour usually means a wrong UTC offset (daylight saving time, a time zone
    /// not set after travel), which [`Self::from_photo_exif`] cannot see: it takes the clock.
    pub fn exif_clock_minus_gps_s(exif: &igi_imaging::exif::PhotoExif) -> Option<i64> {
        let clock = PhotoTime::from_exif(
            exif.date_time_original.as_deref()?,
            Some(exif.offset_time_original.as_deref()?),
        );
        let gps = PhotoTime::from_exif(exif.gps_utc.as_deref()?, Some("+00:00"));
        Some(clock.ok()?.unix_seconds - gps.ok()?.unix_seconds)
    }

    /// A note for a photograph whose clock and GPS stamp are [`CLOCK_GPS_NOTE_S`] or more
    /// apart ([`Self::exif_clock_minus_gps_s`]): the time taken is the clock's.
    pub fn exif_clock_gps_note(exif: &igi_imaging::exif::PhotoExif) -> Option<String> {
        let gap = PhotoTime::exif_clock_minus_gps_s(exif)?;
        (gap.abs() >= CLOCK_GPS_NOTE_S).then(|| {
            let (m, s) = (gap.abs() / 60, gap.abs() % 60);
            let side = if gap > 0 { "ahead of" } else { "behind" };
            format!(
                "its clock (with its UTC offset) is {m} min {s} s {side} its GPS time: the time \
                 taken is the clock's; check the camera's UTC offset (daylight saving time?) or \
                 give the photo a `time`"
            )
        })
    }

    fn from_local(civil: &Civil, nanos: u32, offset_seconds: i32) -> PhotoTime {
        PhotoTime {
            unix_seconds: civil.seconds() - i64::from(offset_seconds),
            nanos,
            offset_seconds,
        }
    }

    /// Whole UTC seconds since 1970-01-01T00:00:00Z (negative before; leap seconds not counted).
    pub fn unix_seconds(&self) -> i64 {
        self.unix_seconds
    }

    /// Nanoseconds past [`unix_seconds`](Self::unix_seconds), in 0..1_000_000_000.
    pub fn nanos(&self) -> u32 {
        self.nanos
    }

    /// The UTC offset the time was written with, in seconds east of Greenwich.
    pub fn offset_seconds(&self) -> i32 {
        self.offset_seconds
    }

    /// The UTC calendar date and time of day.
    pub fn utc(&self) -> UtcDateTime {
        let days = self.unix_seconds.div_euclid(86_400);
        let secs = self.unix_seconds.rem_euclid(86_400) as u32;
        let (year, month, day) = civil_from_days(days);
        UtcDateTime {
            year,
            month,
            day,
            hour: secs / 3600,
            minute: secs / 60 % 60,
            second: f64::from(secs % 60) + f64::from(self.nanos) * 1e-9,
        }
    }

    /// The instant in UTC, RFC 3339 with `Z` (`2026-06-21T06:30:00Z`; a fraction only when
    /// there is one, without trailing zeros).
    pub fn to_rfc3339_utc(&self) -> String {
        self.format(0)
    }

    /// The time as written: RFC 3339 in its own UTC offset (`2026-06-21T09:30:00+03:00`).
    pub fn to_rfc3339(&self) -> String {
        self.format(self.offset_seconds)
    }

    fn format(&self, offset: i32) -> String {
        let local = self.unix_seconds + i64::from(offset);
        let (y, mo, d) = civil_from_days(local.div_euclid(86_400));
        let s = local.rem_euclid(86_400);
        let mut out = format!(
            "{y:04}-{mo:02}-{d:02}T{:02}:{:02}:{:02}",
            s / 3600,
            s / 60 % 60,
            s % 60
        );
        if self.nanos != 0 {
            let frac = format!("{:09}", self.nanos);
            out.push('.');
            out.push_str(frac.trim_end_matches('0'));
        }
        if offset == 0 {
            out.push('Z');
        } else {
            let sign = if offset < 0 { '-' } else { '+' };
            let a = offset.unsigned_abs();
            out.push_str(&format!("{sign}{:02}:{:02}", a / 3600, a / 60 % 60));
        }
        out
    }
}

impl fmt::Display for PhotoTime {
    /// [`PhotoTime::to_rfc3339`]: the time in the offset it was written with.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.to_rfc3339())
    }
}

impl std::str::FromStr for PhotoTime {
    type Err = TimeProblem;

    /// [`PhotoTime::parse_rfc3339`].
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        PhotoTime::parse_rfc3339(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unix(s: &str) -> i64 {
        PhotoTime::parse_rfc3339(s).unwrap().unix_seconds()
    }

    fn err(s: &str) -> TimeProblem {
        PhotoTime::parse_rfc3339(s).unwrap_err()
    }

    /// Unix times computed independently (`date -u -d <time> +%s`, GNU coreutils).
    #[test]
    fn known_instants() {
        let cases = [
            ("1970-01-01T00:00:00Z", 0),
            ("1969-12-31T23:59:59Z", -1),
            ("2000-02-29T12:00:00Z", 951_825_600),
            ("1600-03-01T00:00:00Z", -11_670_912_000),
            ("1900-03-01T00:00:00Z", -2_203_891_200),
            ("2400-02-29T23:59:59Z", 13_574_649_599),
            ("0001-01-01T00:00:00Z", -62_135_596_800),
            ("9999-12-31T23:59:59Z", 253_402_300_799),
            ("2026-06-21T06:30:00Z", 1_782_023_400),
            ("2026-06-21T09:30:00+03:00", 1_782_023_400),
            ("2026-01-01T00:15:00+05:30", 1_767_206_700),
            ("2025-12-31T20:00:00-05:30", 1_767_231_000),
            ("2024-03-10T02:30:00-08:00", 1_710_066_600),
        ];
        for (text, want) in cases {
            assert_eq!(unix(text), want, "{text}");
        }
    }

    #[test]
    fn accepted_spellings() {
        let t = PhotoTime::parse_rfc3339("2026-06-21T09:30:00+03:00").unwrap();
        assert_eq!(t.offset_seconds(), 3 * 3600);
        assert_eq!(t.nanos(), 0);
        assert_eq!(t.to_rfc3339_utc(), "2026-06-21T06:30:00Z");
        assert_eq!(t.to_rfc3339(), "2026-06-21T09:30:00+03:00");
        assert_eq!(t.to_string(), "2026-06-21T09:30:00+03:00");
        // a space for `T`, lower case `t`/`z`, surrounding whitespace
        for s in [
            "2026-06-21 06:30:00Z",
            "2026-06-21t06:30:00z",
            " 2026-06-21T06:30:00+00:00 ",
            "2026-06-21T06:30:00-00:00",
        ] {
            assert_eq!(unix(s), 1_782_023_400, "{s}");
        }
        let t: PhotoTime = "2026-06-21T01:00:00.25-05:30".parse().unwrap();
        assert_eq!(t.unix_seconds(), 1_782_023_400);
        assert_eq!(t.nanos(), 250_000_000);
        assert_eq!(t.offset_seconds(), -(5 * 3600 + 30 * 60));
        assert_eq!(t.to_rfc3339_utc(), "2026-06-21T06:30:00.25Z");
        assert_eq!(t.to_rfc3339(), "2026-06-21T01:00:00.25-05:30");
        // nanosecond digits kept, more truncated
        let t = PhotoTime::parse_rfc3339("2026-06-21T06:30:00.123456789123Z").unwrap();
        assert_eq!(t.nanos(), 123_456_789);
        assert_eq!(
            PhotoTime::parse_rfc3339("1970-01-01T00:00:00.000000001Z")
                .unwrap()
                .nanos(),
            1
        );
        // the extremes of the offset
        assert_eq!(unix("1970-01-01T18:00:00+18:00"), 0);
        assert_eq!(unix("1969-12-31T06:00:00-18:00"), 0);
        // a leap second is read as :59
        assert_eq!(unix("2016-12-31T23:59:60Z"), unix("2016-12-31T23:59:59Z"));
    }

    #[test]
    fn utc_fields_and_formatting_cross_midnight() {
        let t = PhotoTime::parse_rfc3339("2026-01-01T00:15:00.5+05:30").unwrap();
        assert_eq!(
            t.utc(),
            UtcDateTime {
                year: 2025,
                month: 12,
                day: 31,
                hour: 18,
                minute: 45,
                second: 0.5,
            }
        );
        assert_eq!(t.to_rfc3339_utc(), "2025-12-31T18:45:00.5Z");
        let t = PhotoTime::parse_rfc3339("1969-12-31T23:59:59Z").unwrap();
        let u = t.utc();
        assert_eq!(
            (u.year, u.month, u.day, u.hour, u.minute),
            (1969, 12, 31, 23, 59)
        );
        assert_eq!(u.second, 59.0);
        let u = PhotoTime::parse_rfc3339("2026-06-21T09:30:07+03:00")
            .unwrap()
            .utc();
        assert_eq!(
            (u.year, u.month, u.day, u.hour, u.minute),
            (2026, 6, 21, 6, 30)
        );
        assert_eq!(u.second, 7.0);
    }

    #[test]
    fn days_from_civil_is_the_inverse_of_civil_from_days() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(days_from_civil(2000, 3, 1), 11_017);
        assert_eq!(days_from_civil(0, 3, 1), -719_468);
        // every day of years 0..=9999 follows the one before
        let mut prev = civil_from_days(days_from_civil(0, 1, 1) - 1);
        assert_eq!(prev, (-1, 12, 31));
        for z in days_from_civil(0, 1, 1)..=days_from_civil(9999, 12, 31) {
            let (y, m, d) = civil_from_days(z);
            assert_eq!(days_from_civil(y, m, d), z);
            let next = if prev.2 < days_in_month(prev.0, prev.1) {
                (prev.0, prev.1, prev.2 + 1)
            } else if prev.1 < 12 {
                (prev.0, prev.1 + 1, 1)
            } else {
                (prev.0 + 1, 1, 1)
            };
            assert_eq!((y, m, d), next);
            prev = (y, m, d);
        }
        assert_eq!(days_in_month(1900, 2), 28);
        assert_eq!(days_in_month(2000, 2), 29);
        assert_eq!(days_in_month(2024, 2), 29);
    }

    #[test]
    fn refuses_a_time_without_offset() {
        assert_eq!(err("2026-06-21T09:30:00"), TimeProblem::MissingOffset);
        assert_eq!(err("2026-06-21T09:30:00.5"), TimeProblem::MissingOffset);
        assert!(err("2026-06-21T09:30:00")
            .to_string()
            .contains("UTC offset is missing"));
    }

    #[test]
    fn refuses_out_of_range_fields() {
        let field = |field, value, max| TimeProblem::Field {
            field,
            value,
            min: u32::from(field == "month"),
            max,
        };
        assert_eq!(err("2026-13-01T00:00:00Z"), field("month", 13, 12));
        assert_eq!(err("2026-00-01T00:00:00Z"), field("month", 0, 12));
        assert_eq!(err("2026-06-21T24:00:00Z"), field("hour", 24, 23));
        assert_eq!(err("2026-06-21T23:60:00Z"), field("minute", 60, 59));
        assert_eq!(err("2026-06-21T23:59:61Z"), field("second", 61, 60));
        let e = err("2026-02-30T00:00:00Z");
        assert_eq!(
            e,
            TimeProblem::Day {
                year: 2026,
                month: 2,
                day: 30,
                days: 28
            }
        );
        assert_eq!(e.to_string(), "2026-02 has 28 days, not 30");
        assert!(matches!(
            err("2025-02-29T00:00:00Z"),
            TimeProblem::Day { .. }
        ));
        assert!(matches!(
            err("2026-04-31T00:00:00Z"),
            TimeProblem::Day { .. }
        ));
        assert!(matches!(
            err("2026-04-00T00:00:00Z"),
            TimeProblem::Day { .. }
        ));
        assert_eq!(
            err("2026-06-21T00:00:00+18:01"),
            TimeProblem::Offset("+18:01".into())
        );
        assert_eq!(
            err("2026-06-21T00:00:00-19:00"),
            TimeProblem::Offset("-19:00".into())
        );
        assert_eq!(
            err("2026-06-21T00:00:00+03:60"),
            TimeProblem::Offset("+03:60".into())
        );
        assert_eq!(
            err("2026-06-21T00:00:00+19:00").to_string(),
            "UTC offset +19:00 is beyond ±18:00"
        );
    }

    #[test]
    fn refuses_malformed_text() {
        let at = |s: &str| match err(s) {
            TimeProblem::Syntax { at, .. } => at,
            e => panic!("{s}: {e:?}"),
        };
        assert_eq!(at("26-06-21T09:30:00Z"), 3);
        assert_eq!(at("2026/06/21T09:30:00Z"), 5);
        assert_eq!(at("2026-06-21_09:30:00Z"), 11);
        assert_eq!(at("2026-06-21T9:30:00Z"), 13);
        assert_eq!(at("2026-06-21T09:30Z"), 17);
        assert_eq!(at("2026-06-21T09:30:00.Z"), 21);
        assert_eq!(at("2026-06-21T09:30:00+0300"), 23);
        assert_eq!(at("2026-06-21T09:30:00+03"), 23);
        assert_eq!(at("2026-06-21T09:30:00Z junk"), 21);
        assert_eq!(at("2026-06-21T09:30:00 UTC"), 20);
        assert_eq!(at(""), 1);
        assert_eq!(
            err("2026-06-21T09:30:00+0300").to_string(),
            format!("not {RFC3339}: expected `:` in the UTC offset at character 23")
        );
    }

    /// Real photographs (../shared/data/CATALOGUE.md): the Sony writes its offset, the
    /// iPhone 7 does not; the GPS time stands in for a missing offset.
    #[test]
    fn times_of_real_jpegs_and_of_gps_stamps() {
        use igi_imaging::exif::{read_exif, PhotoExif};
        let shared = igi_testkit::shared_data;
        let sony = read_exif(&shared("mirror_ball_ldr/olapietka_sony_a6400/raw1.jpg")).unwrap();
        let t = PhotoTime::from_photo_exif(&sony).unwrap();
        assert_eq!(t.to_rfc3339(), "2023-04-06T16:51:33+02:00");
        assert_eq!(t.to_rfc3339_utc(), "2023-04-06T14:51:33Z");
        let iphone = read_exif(&shared(
            "mirror_ball_ldr/uiuc_cs445_kagrawal_iphone7/ball_10.JPG",
        ))
        .unwrap();
        assert_eq!(
            PhotoTime::from_photo_exif(&iphone),
            Err(TimeProblem::UnknownOffset)
        );
        let gps = PhotoExif {
            gps_utc: Some("2017:10:31 05:39:43".into()),
            ..iphone.clone()
        };
        assert_eq!(
            PhotoTime::from_photo_exif(&gps).unwrap().to_rfc3339(),
            "2017-10-31T05:39:43Z"
        );
        let none = PhotoExif::default();
        let e = PhotoTime::from_photo_exif(&none).unwrap_err();
        assert_eq!(e, TimeProblem::NoExifTime);
        assert!(e.to_string().contains("DateTimeOriginal"), "{e}");
        // the Sony has no GPS stamp, the iPhone no offset: nothing to compare
        assert_eq!(PhotoTime::exif_clock_minus_gps_s(&sony), None);
        assert_eq!(PhotoTime::exif_clock_minus_gps_s(&gps), None);
    }

    /// The Canon EOS R6 CR3 of datasets/fixtures/raw: its clock says 20:24:47 at -08:00
    /// (04:24:47 UTC on the next day), its GPS stamp 03:19:17 UTC, 65 min 30 s earlier; the
    /// time taken is the clock's.
    #[test]
    fn a_clock_an_hour_off_its_gps_stamp_is_measured() {
        use igi_imaging::exif::read_exif;
        let canon = read_exif(&igi_testkit::fixture("raw/canon_r6_header.cr3")).unwrap();
        assert_eq!(PhotoTime::exif_clock_minus_gps_s(&canon), Some(3930));
        assert_eq!(
            PhotoTime::from_photo_exif(&canon).unwrap().to_rfc3339_utc(),
            "2025-09-07T04:24:47Z"
        );
        let behind = igi_imaging::exif::PhotoExif {
            gps_utc: Some("2025:09:07 05:24:47".into()),
            ..canon
        };
        assert_eq!(PhotoTime::exif_clock_minus_gps_s(&behind), Some(-3600));
        let note = PhotoTime::exif_clock_gps_note(&behind).unwrap();
        assert!(note.contains("60 min 0 s behind its GPS time"), "{note}");
        let close = igi_imaging::exif::PhotoExif {
            gps_utc: Some("2025:09:07 04:15:00".into()),
            ..behind
        };
        assert_eq!(PhotoTime::exif_clock_minus_gps_s(&close), Some(587));
        assert_eq!(PhotoTime::exif_clock_gps_note(&close), None);
    }

    #[test]
    fn exif_times() {
        let t = PhotoTime::from_exif("2026:06:21 09:30:00", Some("+03:00")).unwrap();
        assert_eq!(t.unix_seconds(), 1_782_023_400);
        assert_eq!(t.to_rfc3339(), "2026-06-21T09:30:00+03:00");
        // EXIF pads with NULs
        let t = PhotoTime::from_exif("2025:12:31 20:00:00\0", Some("-05:30\0")).unwrap();
        assert_eq!(t.unix_seconds(), 1_767_231_000);
        let e = PhotoTime::from_exif("2026:06:21 09:30:00", None).unwrap_err();
        assert_eq!(e, TimeProblem::UnknownOffset);
        assert!(e.to_string().contains("offset is unknown"), "{e}");
        assert_eq!(
            PhotoTime::from_exif("2026:06:21 09:30:00", Some("   :  ")),
            Err(TimeProblem::UnknownOffset)
        );
        assert_eq!(
            PhotoTime::from_exif("    :  :     :  :  ", Some("+03:00")),
            Err(TimeProblem::Blank)
        );
        assert!(matches!(
            PhotoTime::from_exif("2026-06-21T09:30:00", Some("+03:00")),
            Err(TimeProblem::Syntax { at: 5, .. })
        ));
        assert!(matches!(
            PhotoTime::from_exif("2026:02:30 09:30:00", Some("+03:00")),
            Err(TimeProblem::Day { .. })
        ));
        assert!(matches!(
            PhotoTime::from_exif("2026:06:21 09:30:00", Some("Z")),
            Err(TimeProblem::Syntax { at: 1, .. })
        ));
        assert_eq!(
            PhotoTime::from_exif("2026:06:21 09:30:00", Some("+18:30")),
            Err(TimeProblem::Offset("+18:30".into()))
        );
    }
}
