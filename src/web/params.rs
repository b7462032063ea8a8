//! The query-string parameters of the Jobs and Trends pages, checked: a value that is not
//! what the page expects is a 400 with a one-line reason, never a silent default.

use super::reader::{Cursor, JobQuery, JobState};
use std::collections::HashMap;

/// Jobs shown per page unless `n` says otherwise (at most [`MAX_PAGE_SIZE`]).
pub const PAGE_SIZE: usize = 50;
pub const MAX_PAGE_SIZE: usize = 500;
/// Longest name search accepted (bytes).
const MAX_SEARCH: usize = 200;

/// Days since 1970-01-01 of a `YYYY-MM-DD` date (UTC).
pub fn parse_date(text: &str) -> Option<i64> {
    let b = text.as_bytes();
    if b.len() != 10 || b[4] != b'-' || b[7] != b'-' {
        return None;
    }
    let num = |r: std::ops::Range<usize>| text.get(r)?.parse::<i64>().ok();
    let (y, m, d) = (num(0..4)?, num(5..7)?, num(8..10)?);
    let leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
    let month_days = [
        31,
        28 + i64::from(leap),
        31,
        30,
        31,
        30,
        31,
        31,
        30,
        31,
        30,
        31,
    ];
    if !(1..=12).contains(&m) || d < 1 || d > month_days[(m - 1) as usize] {
        return None;
    }
    // Howard Hinnant's days_from_civil.
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    Some(era * 146_097 + doe - 719_468)
}

fn value<'a>(params: &'a HashMap<String, String>, key: &str) -> &'a str {
    params.get(key).map(|v| v.trim()).unwrap_or("")
}

fn id(params: &HashMap<String, String>, key: &str) -> Result<Option<i64>, String> {
    match value(params, key) {
        "" => Ok(None),
        v => v
            .parse::<i64>()
            .map(Some)
            .map_err(|_| format!("{key} must be a job id")),
    }
}

/// The list query from the page's parameters.
pub fn job_query(params: &HashMap<String, String>) -> Result<JobQuery, String> {
    let state = match value(params, "state") {
        "" => None,
        s => Some(JobState::parse(s).ok_or_else(|| {
            "state must be one of queued, running, done, failed, quarantined".to_string()
        })?),
    };
    let day = |key: &str| -> Result<Option<i64>, String> {
        match value(params, key) {
            "" => Ok(None),
            v => parse_date(v)
                .map(Some)
                .ok_or_else(|| format!("{key} must be a date such as 2026-11-30")),
        }
    };
    let from_ms = day("from")?.map(|d| d * 86_400_000);
    // `to` is the last day shown, inclusive.
    let to_ms = day("to")?.map(|d| (d + 1) * 86_400_000);
    let text = match value(params, "q") {
        "" => None,
        t if t.len() > MAX_SEARCH => {
            return Err(format!("q: at most {MAX_SEARCH} bytes"));
        }
        t => Some(t.to_string()),
    };
    let cursor = match (id(params, "before")?, id(params, "after")?) {
        (Some(_), Some(_)) => return Err("give before or after, not both".into()),
        (Some(b), None) => Cursor::Before(b),
        (None, Some(a)) => Cursor::After(a),
        (None, None) => Cursor::Newest,
    };
    let root = match value(params, "root") {
        "" => None,
        r => Some(r.to_string()),
    };
    let limit = match value(params, "n") {
        "" => PAGE_SIZE,
        v => v
            .parse::<usize>()
            .ok()
            .filter(|n| (1..=MAX_PAGE_SIZE).contains(n))
            .ok_or_else(|| format!("n must be 1..={MAX_PAGE_SIZE}"))?,
    };
    Ok(JobQuery {
        state,
        root,
        from_ms,
        to_ms,
        text,
        cursor,
        limit,
    })
}

/// The Trends window in days (default 28, 1..=366).
pub fn trend_days(params: &HashMap<String, String>) -> Result<i64, String> {
    match value(params, "days") {
        "" => Ok(28),
        v => v
            .parse::<i64>()
            .ok()
            .filter(|d| (1..=366).contains(d))
            .ok_or_else(|| "days must be 1..=366".into()),
    }
}

/// The `from`/`to` texts as the form shows them again.
pub fn echo(params: &HashMap<String, String>, key: &str) -> String {
    value(params, key).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(pairs: &[(&str, &str)]) -> HashMap<String, String> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }

    #[test]
    fn dates_round_trip_with_iso_time() {
        for (text, days) in [
            ("1970-01-01", 0),
            ("2000-02-29", 11_016),
            ("2026-12-03", 20_790),
        ] {
            assert_eq!(parse_date(text), Some(days), "{text}");
            assert_eq!(
                &crate::store::query::iso_time(days * 86_400_000)[..10],
                text
            );
        }
        for bad in ["2026-02-29", "2026-13-01", "2026-1-01", "x", "2026-12-3x"] {
            assert_eq!(parse_date(bad), None, "{bad}");
        }
    }

    #[test]
    fn bad_values_are_refused_with_a_reason() {
        assert!(
            job_query(&map(&[("state", "exploded")]))
                .unwrap_err()
                .contains("state")
        );
        assert!(
            job_query(&map(&[("before", "1;drop")]))
                .unwrap_err()
                .contains("before")
        );
        assert!(
            job_query(&map(&[("from", "yesterday")]))
                .unwrap_err()
                .contains("from")
        );
        assert!(job_query(&map(&[("before", "3"), ("after", "1")])).is_err());
        let q = job_query(&map(&[
            ("state", "done"),
            ("to", "1970-01-01"),
            ("before", "9"),
        ]))
        .unwrap();
        assert_eq!(q.state, Some(JobState::Done));
        assert_eq!(q.to_ms, Some(86_400_000));
        assert_eq!(q.cursor, Cursor::Before(9));
    }
}
