//! Durations on the command line: the one parser of every option that takes a length of time
//! (`run`, `tap`, `simulate --duration`, `nav-eval --window` / `--characterise`, `train
//! --horizon` / `--still-window`, `denoise --plot-window` / `--plot-from`, `list --stats-wait`,
//! and the examples).
//!
//! The forms are humantime's: a number with a unit (`500ms`, `10s`, `1.5s`, `90min`, `2m`, `3h`,
//! `0.5h`, `2d`), or several (`1h 30min`). One extension: a plain number is seconds (`600`,
//! `0.25`). humantime insists on a unit, but these options always took bare seconds, and the
//! docs/commands.md ("Conventions"), scripts and tests pass them so.

use std::time::Duration;

/// The accepted forms, as the error messages name them.
pub const FORMS: &str = "use a number with a unit (500ms, 10s, 1.5s, 90min, 3h, 2d, or 1h 30min; \
units ns, us, ms, s, min or m, h, d, w) or a plain number of seconds (600, 0.25)";

/// The longest duration accepted (about 31.7 years): a deadline `now + duration` must not
/// overflow, and nothing here runs longer.
pub const MAX: Duration = Duration::from_secs(1_000_000_000);

/// Parse a positive duration: `"10s"`, `"250ms"`, `"1.5s"`, `"90min"`, `"3h"`, `"600"` (seconds).
///
/// Zero, negative, non-finite and longer than [`MAX`] are refused. The error names the value
/// and the accepted forms (clap adds the option's name when this is a `value_parser`).
pub fn parse_duration(text: &str) -> Result<Duration, String> {
    let s = text.trim();
    let refuse = |why: &str| format!("{text:?} is not a positive duration: {why}; {FORMS}");
    if s.is_empty() {
        return Err(refuse("it is empty"));
    }
    if s.starts_with('-') {
        return Err(refuse("it is negative"));
    }
    let d = match s.parse::<f64>() {
        // The extension: a plain number is seconds.
        Ok(secs) if !secs.is_finite() => return Err(refuse("it is not finite")),
        Ok(secs) if secs > MAX.as_secs_f64() => return Err(refuse("it is too long")),
        Ok(secs) => Duration::try_from_secs_f64(secs).map_err(|_| refuse("it is not a number"))?,
        Err(_) => humantime::parse_duration(s).map_err(|e| refuse(&reason(s, &e)))?,
    };
    if d.is_zero() {
        return Err(refuse("it is zero"));
    }
    if d > MAX {
        return Err(refuse("it is too long"));
    }
    Ok(d)
}

/// A point in a record counted from its start (`--plot-from`): as [`parse_duration`], but zero
/// (`0`, `0s`) is allowed.
pub fn parse_offset(text: &str) -> Result<Duration, String> {
    parse_duration(text).or_else(|e| {
        let s = text.trim();
        let zero = !s.starts_with('-')
            && (s.parse::<f64>().is_ok_and(|v| v == 0.0)
                || humantime::parse_duration(s).is_ok_and(|d| d.is_zero()));
        if zero {
            Ok(Duration::ZERO)
        } else {
            Err(e)
        }
    })
}

/// [`parse_duration`] in seconds, for options that turn a duration into a count of samples.
pub fn parse_seconds(text: &str) -> Result<f64, String> {
    parse_duration(text).map(|d| d.as_secs_f64())
}

/// humantime's error in our words (its own list of units is not the one we document).
fn reason(s: &str, e: &humantime::DurationError) -> String {
    use humantime::DurationError as E;
    match e {
        E::UnknownUnit { unit, .. } if unit.is_empty() => "a unit is missing".into(),
        E::UnknownUnit { unit, .. } => format!("unknown unit {unit:?}"),
        E::InvalidCharacter(at) => match s.get(*at..).and_then(|r| r.chars().next()) {
            Some(c) => format!("unexpected character {c:?}"),
            None => "unexpected character".into(),
        },
        E::NumberExpected(_) => "a number is missing".into(),
        E::NumberOverflow => "it is too long, or has more decimals than nanoseconds hold".into(),
        E::Empty => "it is empty".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ok(s: &str) -> Duration {
        parse_duration(s).unwrap_or_else(|e| panic!("{s}: {e}"))
    }

    #[test]
    fn humantime_forms_and_plain_seconds() {
        assert_eq!(ok("10s"), Duration::from_secs(10));
        assert_eq!(ok("250ms"), Duration::from_millis(250));
        assert_eq!(ok("100us"), Duration::from_micros(100));
        assert_eq!(ok("2m"), Duration::from_secs(120));
        assert_eq!(ok("90min"), Duration::from_secs(5400));
        assert_eq!(ok("3h"), Duration::from_secs(10800));
        assert_eq!(ok("2.5d"), Duration::from_secs(216_000));
        assert_eq!(ok("1h 30min"), Duration::from_secs(5400));
        assert_eq!(ok(" 45s "), Duration::from_secs(45));
        // Fractions with a unit are humantime's own; plain numbers are our extension.
        assert_eq!(ok("1.5s"), Duration::from_millis(1500));
        assert_eq!(ok("0.5h"), Duration::from_secs(1800));
        assert_eq!(ok("1.5"), Duration::from_millis(1500));
        assert_eq!(ok("600"), Duration::from_secs(600));
        assert_eq!(ok("1e3"), Duration::from_secs(1000));
    }

    #[test]
    fn refusals_name_the_value_the_reason_and_the_forms() {
        for (bad, why) in [
            ("0s", "zero"),
            ("0", "zero"),
            ("0h", "zero"),
            ("-1s", "negative"),
            ("-1", "negative"),
            ("soon", "a number is missing"),
            ("3 weeks ago", "a number is missing"),
            ("h", "a number is missing"),
            ("10x", "unknown unit \"x\""),
            ("", "empty"),
            ("inf", "not finite"),
            ("NaN", "not finite"),
            ("1e300", "too long"),
            ("40y", "too long"),
            ("1/2s", "unexpected character '/'"),
            ("1.3333333333333333s", "more decimals"),
        ] {
            let e = parse_duration(bad).expect_err(bad);
            assert!(
                e.starts_with(&format!("{bad:?} is not a positive duration")),
                "{e}"
            );
            assert!(e.contains(why), "{bad}: {e}");
            assert!(
                e.contains("90min") && e.contains("plain number of seconds"),
                "{e}"
            );
        }
    }

    #[test]
    fn offsets_take_zero_and_refuse_what_durations_refuse() {
        assert_eq!(parse_offset("0"), Ok(Duration::ZERO));
        assert_eq!(parse_offset("0s"), Ok(Duration::ZERO));
        assert_eq!(parse_offset("0.0"), Ok(Duration::ZERO));
        assert_eq!(parse_offset("90s"), Ok(Duration::from_secs(90)));
        for bad in ["-0", "-1s", "soon", "", "inf"] {
            let e = parse_offset(bad).expect_err(bad);
            assert!(e.contains("is not a positive duration"), "{bad}: {e}");
        }
    }

    #[test]
    fn seconds() {
        assert_eq!(parse_seconds("90min"), Ok(5400.0));
        assert_eq!(parse_seconds("500ms"), Ok(0.5));
        assert!(parse_seconds("0").is_err());
    }
}
