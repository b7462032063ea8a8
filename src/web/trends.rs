//! The Trends page: per watched folder, one small SVG plot per figure (distance RMS,
//! texture deviation, processing time, failures) with one point per UTC day, drawn on the
//! server so that drift shows at a glance without any script.

use super::html::{self, esc, figure, shown};
use super::reader::TrendDay;
use std::fmt::Write;

const W: f64 = 420.0;
const H: f64 = 150.0;
const LEFT: f64 = 56.0;
const RIGHT: f64 = 10.0;
const TOP: f64 = 22.0;
const BOTTOM: f64 = 24.0;

/// `2026-12-03` from days since 1970-01-01.
fn day_label(day: i64) -> String {
    crate::store::query::iso_time(day * 86_400_000)[..10].to_string()
}

/// One plot: `points` are (day, value) in `first..=last`; days without a value are gaps.
pub fn plot(title: &str, unit: &str, first: i64, last: i64, points: &[(i64, f64)]) -> String {
    let span = (last - first).max(1) as f64;
    let max = points.iter().map(|p| p.1).fold(0.0f64, f64::max);
    let top = if max > 0.0 { max * 1.1 } else { 1.0 };
    let x = |d: i64| LEFT + (d - first) as f64 / span * (W - LEFT - RIGHT);
    let y = |v: f64| TOP + (1.0 - v / top) * (H - TOP - BOTTOM);
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" viewBox=\"0 0 {W} {H}\" role=\"img\">\
         <title>{t}</title><text x=\"{LEFT}\" y=\"14\" font-size=\"12\">{t} ({u})</text>\
         <line x1=\"{LEFT}\" y1=\"{b}\" x2=\"{r}\" y2=\"{b}\" stroke=\"#999\"/>\
         <line x1=\"{LEFT}\" y1=\"{TOP}\" x2=\"{LEFT}\" y2=\"{b}\" stroke=\"#999\"/>\
         <text x=\"{lx}\" y=\"{ty}\" font-size=\"10\" text-anchor=\"end\">{top_label}</text>\
         <text x=\"{lx}\" y=\"{b}\" font-size=\"10\" text-anchor=\"end\">0</text>\
         <text x=\"{LEFT}\" y=\"{dy}\" font-size=\"10\">{d0}</text>\
         <text x=\"{r}\" y=\"{dy}\" font-size=\"10\" text-anchor=\"end\">{d1}</text>",
        t = esc(title),
        u = esc(unit),
        b = H - BOTTOM,
        r = W - RIGHT,
        lx = LEFT - 4.0,
        ty = TOP + 8.0,
        top_label = figure(Some(top)),
        dy = H - 8.0,
        d0 = day_label(first),
        d1 = day_label(last),
    );
    // A line through consecutive days; a day without a value breaks it.
    let mut path = String::new();
    let mut previous: Option<i64> = None;
    for &(d, v) in points {
        let cmd = if previous == Some(d - 1) { 'L' } else { 'M' };
        let _ = write!(path, "{cmd}{:.1},{:.1} ", x(d), y(v));
        previous = Some(d);
    }
    if !path.is_empty() {
        let _ = write!(
            s,
            "<path d=\"{path}\" fill=\"none\" stroke=\"#27a\" stroke-width=\"1.5\"/>"
        );
    }
    for &(d, v) in points {
        let _ = write!(
            s,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2.5\" fill=\"#27a\"><title>{} {}</title></circle>",
            x(d),
            y(v),
            day_label(d),
            figure(Some(v))
        );
    }
    s.push_str("</svg>");
    s
}

/// The Trends page over the days `first..=last`.
pub fn trends_page(days: &[TrendDay], first: i64, last: i64, window_days: i64) -> String {
    let mut body = format!(
        "<h1>Trends</h1><p>Per watched folder and UTC day, the last {window_days} days: the mean over the day's \
         finished jobs. Other windows: <a href=\"/trends?days=7\">7</a> <a href=\"/trends?days=28\">28</a> \
         <a href=\"/trends?days=91\">91</a> <a href=\"/trends?days=365\">365</a> days.</p>"
    );
    if days.is_empty() {
        body.push_str("<p>No job finished in this window.</p>");
    }
    let mut roots: Vec<&str> = days.iter().map(|d| d.root.as_str()).collect();
    roots.dedup();
    for root in roots {
        let mine: Vec<&TrendDay> = days.iter().filter(|d| d.root == root).collect();
        let series = |f: &dyn Fn(&TrendDay) -> Option<f64>| -> Vec<(i64, f64)> {
            mine.iter()
                .filter_map(|d| f(d).filter(|v| v.is_finite()).map(|v| (d.day, v)))
                .collect()
        };
        let _ = write!(
            body,
            "<h2><code>{}</code></h2><div class=\"plots\">",
            shown(root)
        );
        body.push_str(&plot(
            "distance RMS",
            "mesh units",
            first,
            last,
            &series(&|d| d.distance_rms),
        ));
        body.push_str(&plot(
            "texture deviation RMS",
            "0–255",
            first,
            last,
            &series(&|d| d.texture_rms),
        ));
        body.push_str(&plot(
            "processing time",
            "s",
            first,
            last,
            &series(&|d| d.process_ms.map(|ms| ms / 1e3)),
        ));
        body.push_str(&plot(
            "failures",
            "jobs",
            first,
            last,
            &series(&|d| Some(d.failed as f64)),
        ));
        body.push_str("</div>");
    }
    html::page("Trends", &body)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plot_breaks_the_line_at_a_missing_day_and_escapes_its_title() {
        let svg = plot("a<b", "u", 10, 20, &[(10, 1.0), (11, 2.0), (13, 1.5)]);
        assert!(svg.contains("a&lt;b"), "{svg}");
        let path = svg.split("d=\"").nth(1).unwrap();
        assert_eq!(path.matches('M').count(), 2, "{path}");
        assert_eq!(path.matches('L').count(), 1, "{path}");
        assert_eq!(svg.matches("<circle").count(), 3);
    }
}
