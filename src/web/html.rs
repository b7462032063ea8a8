//! HTML building blocks: the one escaping function, query-string encoding, the page frame.
//!
//! Rule: every string that did not come from this module's own literals goes through
//! [`esc`] on its way into a page, attribute values included (they are always quoted with
//! `"`). Input-derived strings are made printable first ([`crate::text`]): control
//! characters and bytes that are not UTF-8 shown as escapes, then HTML-escaped here.

use std::fmt::Write;

/// `text` safe inside HTML text and inside a `"`-quoted attribute value.
pub fn esc(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// Input-derived text (a name, an error) made printable, bounded and HTML-escaped.
pub fn shown(text: &str) -> String {
    esc(&crate::text::bounded(text, crate::text::MAX_SHOWN))
}

/// `text` percent-encoded for a query-string value (everything but unreserved characters).
pub fn url_value(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for b in text.bytes() {
        if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.' | b'~') {
            out.push(b as char);
        } else {
            let _ = write!(out, "%{b:02X}");
        }
    }
    out
}

/// A query string (`?a=1&b=2`, already `&amp;`-escaped for an attribute) from the pairs
/// whose value is not empty.
pub fn query(pairs: &[(&str, String)]) -> String {
    let parts: Vec<String> = pairs
        .iter()
        .filter(|(_, v)| !v.is_empty())
        .map(|(k, v)| format!("{k}={}", url_value(v)))
        .collect();
    if parts.is_empty() {
        String::new()
    } else {
        format!("?{}", parts.join("&amp;"))
    }
}

/// The whole page around `body`; `title` is plain text (escaped here).
pub fn page(title: &str, body: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
         <title>{} · scanmill</title><link rel=\"stylesheet\" href=\"/static/style.css\"></head>\
         <body><nav><b>scanmill</b> <a href=\"/\">Jobs</a> <a href=\"/trends\">Trends</a> \
         <a href=\"/health\">Health</a> <a href=\"/metrics\">Metrics</a></nav><main>\n{body}\n</main></body></html>\n",
        esc(title)
    )
}

/// A number with its thousands grouped by narrow no-break spaces, or `–`.
pub fn count(v: Option<i64>) -> String {
    let Some(v) = v else { return "–".into() };
    let digits = v.unsigned_abs().to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            out.push('\u{202f}');
        }
        out.push(c);
    }
    if v < 0 { format!("-{out}") } else { out }
}

/// A duration in milliseconds for people: `850 ms`, `12.4 s`, `3.2 min`, or `–`.
pub fn duration_ms(ms: Option<f64>) -> String {
    match ms {
        Some(ms) if ms.is_finite() && ms < 1000.0 => format!("{ms:.0} ms"),
        Some(ms) if ms.is_finite() && ms < 120_000.0 => format!("{:.1} s", ms / 1e3),
        Some(ms) if ms.is_finite() => format!("{:.1} min", ms / 60e3),
        _ => "–".into(),
    }
}

/// A figure with about four significant digits, or `–`.
pub fn figure(v: Option<f64>) -> String {
    match v {
        Some(v) if v.is_finite() && v != 0.0 && (v.abs() >= 1e5 || v.abs() < 1e-3) => {
            format!("{v:.3e}")
        }
        Some(v) if v.is_finite() => format!("{v:.4}"),
        _ => "–".into(),
    }
}

/// The stylesheet (served as a file: the pages' Content-Security-Policy allows no inline
/// style or script).
pub const STYLE: &str = "body{font:14px/1.4 system-ui,sans-serif;margin:0;color:#222;background:#fafafa}\
nav{background:#234;color:#fff;padding:.6em 1em}nav a{color:#cde;margin-left:1em}\
main{padding:1em}table{border-collapse:collapse;background:#fff}\
td,th{border:1px solid #ddd;padding:.25em .5em;text-align:left;vertical-align:top}\
th{background:#eef}td.n{text-align:right;white-space:nowrap;font-variant-numeric:tabular-nums}td.t{white-space:nowrap}\
img.thumb{width:96px;height:auto;background:#eee}img.full{max-width:100%;height:auto}\
.state-done{color:#070}.state-failed,.state-quarantined{color:#a00}.state-running{color:#05a}\
form.filters{margin-bottom:1em}form.filters label{margin-right:.8em}\
pre{background:#fff;border:1px solid #ddd;padding:.5em;overflow:auto;max-height:40em}\
.pager a{margin-right:1em}.err{color:#a00}svg{background:#fff;border:1px solid #ddd;margin:.3em}\
code{word-break:break-all}\n";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn esc_neutralises_markup_and_quotes() {
        assert_eq!(
            esc("<script>alert(\"x\")</script>&'"),
            "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;&amp;&#39;"
        );
    }

    #[test]
    fn shown_escapes_controls_then_markup() {
        assert_eq!(shown("a\n<b>"), "a\\n&lt;b&gt;");
    }

    #[test]
    fn query_encodes_values_and_skips_empty_ones() {
        assert_eq!(
            query(&[("q", "a b&<\"".into()), ("state", String::new())]),
            "?q=a%20b%26%3C%22"
        );
        assert_eq!(
            query(&[("a", "1".into()), ("b", "2".into())]),
            "?a=1&amp;b=2"
        );
    }

    #[test]
    fn numbers_for_people() {
        assert_eq!(count(Some(1234567)), "1\u{202f}234\u{202f}567");
        assert_eq!(count(None), "–");
        assert_eq!(duration_ms(Some(12_400.0)), "12.4 s");
        assert_eq!(figure(Some(0.000123)), "1.230e-4");
    }
}
