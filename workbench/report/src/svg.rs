//! The workbench's one plotter: SVG charts for the compare report (time traces, error
//! budget, history) and the identification reports (x-y points with error bars and fitted
//! curves).
//!
//! Drawing is done by the `plotters` crate's SVG backend (issue 10: one plotting module,
//! not a hand-written one). It is built with `default-features = false` and only
//! `svg_backend` + `line_series`: no `ttf`, so no system font library (font-kit,
//! freetype, fontconfig) is linked; labels are plain SVG `<text>` that the browser lays
//! out. The output is inline SVG without scripts or fonts, so the HTML report stays one
//! self-contained file. What plotters does not do is done here: the min/max envelope
//! decimation of long runs, the tick-label format, the legends and the `role`/`aria-label`
//! of each chart.
//!
//! Long runs are drawn as a per-pixel-column min/max envelope: 70,000 samples become
//! ~2 points per pixel and a one-sample spike still shows.

use std::error::Error;

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// Chart size in px and the plot area's margins.
const W: f64 = 900.0;
const ML: f64 = 70.0;
const MR: f64 = 15.0;
const MT: f64 = 24.0;
const MB: f64 = 34.0;

/// A drawing step's result; a failed chart still ends as well-formed SVG (the backend
/// closes its tags when dropped).
type Drawn = Result<(), Box<dyn Error>>;

/// One line of a line chart.
pub struct Series<'a> {
    pub values: &'a [f64],
    pub color: &'a str,
    pub label: &'a str,
}

/// Escape text for SVG/HTML.
pub fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            _ => o.push(c),
        }
    }
    o
}

/// A short number for an axis label.
fn tick_label(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        format!("{v:.1e}")
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 1.0 {
        let s = format!("{v:.2}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// Finite min and max of `vals`, padded by 5 %; a flat or empty range is widened.
fn padded_range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = vals
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    if hi - lo <= 1e-12 * (lo.abs() + hi.abs()).max(1e-12) {
        let pad = (lo.abs() * 0.01).max(1e-6);
        return (lo - pad, hi + pad);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

/// The y range of a line chart's series.
fn y_range(series: &[Series<'_>]) -> (f64, f64) {
    padded_range(series.iter().flat_map(|s| s.values.iter().copied()))
}

/// `#rgb` or `#rrggbb` as a plotters colour; anything else is black.
fn rgb(c: &str) -> RGBColor {
    let h = c.trim().trim_start_matches('#');
    let hex = |s: &str| u8::from_str_radix(s, 16).ok();
    if !h.is_ascii() {
        return BLACK;
    }
    let parts = match h.len() {
        6 => (hex(&h[0..2]), hex(&h[2..4]), hex(&h[4..6])),
        3 => (hex(&h[0..1]).map(|v| v * 17), hex(&h[1..2]).map(|v| v * 17), hex(&h[2..3]).map(|v| v * 17)),
        _ => (None, None, None),
    };
    match parts {
        (Some(r), Some(g), Some(b)) => RGBColor(r, g, b),
        _ => BLACK,
    }
}

/// Grey `#vvvvvv`.
fn grey(v: u8) -> RGBColor {
    RGBColor(v, v, v)
}

/// A sans-serif text style of `px` CSS pixels (the SVG backend writes size / 1.24).
fn font(px: f64) -> TextStyle<'static> {
    TextStyle::from(("sans-serif", px * 1.24).into_font())
}

/// A bold title.
fn title_font(px: f64) -> TextStyle<'static> {
    TextStyle::from(("sans-serif", px * 1.24, FontStyle::Bold).into_font())
}

/// Anchored text style.
fn anchored(s: TextStyle<'static>, h: HPos, v: VPos) -> TextStyle<'static> {
    s.pos(Pos::new(h, v))
}

/// Draw into an SVG of `w` x `h` px with plotters and return it compact (no newlines
/// between tags) and labelled for screen readers.
fn render(
    title: &str,
    w: f64,
    h: f64,
    draw: impl FnOnce(&DrawingArea<SVGBackend<'_>, plotters::coord::Shift>) -> Drawn,
) -> String {
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (w.round().max(1.0) as u32, h.round().max(1.0) as u32))
            .into_drawing_area();
        // A chart that could not be drawn completely is still returned, well formed.
        let _ = draw(&root);
        let _ = root.present();
    }
    let s = buf.replace(">\n", ">").replace("\n</", "</");
    s.trim_end().replacen("<svg ", &format!(r#"<svg role="img" aria-label="{}" "#, esc(title)), 1)
}

/// An axis with given tick values (plotters' `with_key_points` gives up the label
/// formatter, which the mesh needs).
struct Keyed<R> {
    inner: R,
    keys: Vec<f64>,
}

impl<R: Ranged<ValueType = f64>> Ranged for Keyed<R> {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        self.inner.map(v, limit)
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            Vec::new()
        } else {
            self.keys.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.inner.range()
    }
}

/// Min/max envelope of `y` over `cols` pixel columns, as (t, y) points in time order.
fn envelope(t: &[f64], y: &[f64], cols: usize) -> Vec<(f64, f64)> {
    let n = t.len().min(y.len());
    let mut pts = Vec::new();
    if n == 0 {
        return pts;
    }
    let per = n.div_ceil(cols.max(1)).max(1);
    let mut k = 0;
    while k < n {
        let end = (k + per).min(n);
        let (mut lo, mut hi, mut ilo, mut ihi) = (f64::INFINITY, f64::NEG_INFINITY, k, k);
        for (i, &v) in y.iter().enumerate().take(end).skip(k) {
            if v.is_finite() && t[i].is_finite() {
                if v < lo {
                    lo = v;
                    ilo = i;
                }
                if v > hi {
                    hi = v;
                    ihi = i;
                }
            }
        }
        if lo.is_finite() {
            // Keep the time order of the two extremes.
            let (a, b) = if ilo <= ihi { (ilo, ihi) } else { (ihi, ilo) };
            pts.push((t[a], y[a]));
            if a != b {
                pts.push((t[b], y[b]));
            }
        }
        k = end;
    }
    pts
}

/// A time chart of one or more series with shaded time spans (`[start, end]` s).
pub fn line_chart(
    title: &str,
    unit: &str,
    t: &[f64],
    series: &[Series<'_>],
    shade: &[(f64, f64)],
    height: f64,
) -> String {
    let (t0, t1) = match (t.first(), t.last()) {
        (Some(a), Some(b)) if a.is_finite() && b > a && b.is_finite() => (*a, *b),
        (Some(a), _) if a.is_finite() => (*a, a + 1.0),
        _ => (0.0, 1.0),
    };
    let (lo, hi) = y_range(series);
    let cols = (W - ML - MR) as usize;
    render(title, W, height, |root| {
        let mut chart = ChartBuilder::on(root)
            .margin_top(MT as i32)
            .margin_right(MR as i32)
            .x_label_area_size(MB as i32)
            .y_label_area_size(ML as i32)
            .build_cartesian_2d(t0..t1, lo..hi)?;
        chart.draw_series(shade.iter().filter(|(a, b)| b.min(t1) > a.max(t0)).map(|(a, b)| {
            Rectangle::new([(a.max(t0), hi), (b.min(t1), lo)], RGBColor(0xf6, 0xc3, 0x43).mix(0.35).filled())
        }))?;
        chart
            .configure_mesh()
            .x_labels(10)
            .y_labels(5)
            .x_label_formatter(&|v| tick_label(*v))
            .y_label_formatter(&|v| tick_label(*v))
            .bold_line_style(grey(0xe3))
            .light_line_style(TRANSPARENT)
            .axis_style(grey(0x99))
            .label_style(font(11.0))
            .axis_desc_style(font(11.0))
            .x_desc("time [s]")
            .y_desc(format!("[{unit}]"))
            .draw()?;
        if lo < 0.0 && hi > 0.0 {
            chart.draw_series(std::iter::once(PathElement::new(vec![(t0, 0.0), (t1, 0.0)], grey(0x88))))?;
        }
        for se in series {
            chart
                .draw_series(LineSeries::new(envelope(t, se.values, cols), rgb(se.color).stroke_width(1)))?;
        }
        root.draw(&Text::new(title.to_string(), (ML as i32, 4), title_font(13.0)))?;
        let mut lx = W - MR - 8.0;
        for se in series.iter().rev() {
            lx -= 12.0 + 7.0 * se.label.chars().count() as f64;
            let x = lx as i32;
            root.draw(&PathElement::new(vec![(x, 12), (x + 10, 12)], rgb(se.color).stroke_width(3)))?;
            root.draw(&Text::new(
                se.label.to_string(),
                (x + 13, 12),
                anchored(font(11.0), HPos::Left, VPos::Center),
            ))?;
            lx -= 10.0;
        }
        Ok(())
    })
}

/// One bar group of the error-budget chart.
pub struct Bar<'a> {
    pub label: &'a str,
    /// Share of the squared error, 0..1.
    pub error: f64,
    /// Share of the samples, 0..1.
    pub samples: f64,
}

/// Horizontal bars: error share (solid) against sample share (thin) per region.
pub fn budget_chart(title: &str, bars: &[Bar<'_>]) -> String {
    let label_w = 300;
    let row = 26;
    let h = MT + 12.0 + (row * bars.len() as i32) as f64 + 20.0;
    let pw = (W - label_w as f64 - MR - 60.0) as i32;
    let red = RGBColor(0xc0, 0x39, 0x2b);
    let w = W as i32;
    render(title, W, h, |root| {
        let left =
            |s: String, x: i32, y: i32| Text::new(s, (x, y), anchored(font(11.0), HPos::Left, VPos::Center));
        root.draw(&Text::new(title.to_string(), (4, 4), title_font(13.0)))?;
        root.draw(&Rectangle::new([(w - 330, 6), (w - 318, 14)], red.filled()))?;
        root.draw(&left("share of squared error".into(), w - 314, 10))?;
        root.draw(&Rectangle::new([(w - 160, 9), (w - 148, 12)], grey(0x55).filled()))?;
        root.draw(&left("share of samples".into(), w - 144, 10))?;
        for (i, b) in bars.iter().enumerate() {
            let y = MT as i32 + 12 + row * i as i32;
            let we = (b.error.clamp(0.0, 1.0) * pw as f64).round() as i32;
            let ws = (b.samples.clamp(0.0, 1.0) * pw as f64).round() as i32;
            root.draw(&Text::new(
                b.label.to_string(),
                (label_w - 6, y + 7),
                anchored(font(11.0), HPos::Right, VPos::Center),
            ))?;
            root.draw(&Rectangle::new([(label_w, y), (label_w + pw, y + 14)], grey(0xf2).filled()))?;
            if we > 0 {
                root.draw(&Rectangle::new([(label_w, y), (label_w + we, y + 14)], red.filled()))?;
            }
            if ws > 0 {
                root.draw(&Rectangle::new([(label_w, y + 16), (label_w + ws, y + 20)], grey(0x55).filled()))?;
            }
            root.draw(&left(
                format!("{:.0} % / {:.0} %", 100.0 * b.error, 100.0 * b.samples),
                label_w + pw + 6,
                y + 7,
            ))?;
        }
        Ok(())
    })
}

/// Line colours for charts with many series (colour-blind-safe order first).
pub const PALETTE: [&str; 10] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
    "#17becf",
];

/// Error per iteration of the improve-the-model loop: one line with markers per series
/// (`label`, value per iteration, `None` where not recorded), x = iteration 1..n, y on a
/// log axis because a good effect cuts an error by factors, not by fixed amounts.
pub fn history_chart(title: &str, y_label: &str, series: &[(String, Vec<Option<f64>>)]) -> String {
    let n = series.iter().map(|(_, v)| v.len()).max().unwrap_or(0).max(1);
    let legend_w = 170.0;
    let h = 300.0;
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in series.iter().flat_map(|(_, v)| v.iter().flatten()).filter(|v| v.is_finite() && **v > 0.0) {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    if !lo.is_finite() {
        (lo, hi) = (0.1, 1.0);
    }
    let (llo, mut lhi) = (lo.log10().floor(), hi.log10().ceil());
    if lhi <= llo {
        lhi = llo + 1.0;
    }
    // Grid: decades, and 2 and 5 within them when the range is short.
    let mults: &[f64] = if lhi - llo <= 2.0 { &[1.0, 2.0, 5.0] } else { &[1.0] };
    let mut y_keys = Vec::new();
    let mut e = llo;
    while e <= lhi {
        y_keys.extend(mults.iter().map(|m| m * 10f64.powf(e)).filter(|v| v.log10() <= lhi + 1e-9));
        e += 1.0;
    }
    // Iterations 1..n; one iteration sits in the middle.
    let (x0, x1) = if n == 1 { (0.5, 1.5) } else { (1.0, n as f64) };
    let every = n.div_ceil(20).max(1);
    let x_keys: Vec<f64> = (1..=n).step_by(every).map(|i| i as f64).collect();
    render(title, W, h, |root| {
        let mut chart = ChartBuilder::on(root)
            .margin_top(MT as i32)
            .margin_right((MR + legend_w) as i32)
            .x_label_area_size(MB as i32)
            .y_label_area_size(ML as i32)
            .build_cartesian_2d(
                Keyed { inner: RangedCoordf64::from(x0..x1), keys: x_keys },
                Keyed { inner: LogCoord::from((10f64.powf(llo)..10f64.powf(lhi)).log_scale()), keys: y_keys },
            )?;
        chart
            .configure_mesh()
            .x_label_formatter(&|v| format!("{}", v.round()))
            .y_label_formatter(&|v| tick_label(*v))
            .bold_line_style(grey(0xd8))
            .light_line_style(TRANSPARENT)
            .axis_style(grey(0x99))
            .label_style(font(11.0))
            .axis_desc_style(font(11.0))
            .x_desc("iteration")
            .y_desc(format!("{y_label} (log)"))
            .draw()?;
        for (k, (label, v)) in series.iter().enumerate() {
            let color = rgb(PALETTE[k % PALETTE.len()]);
            let pts: Vec<(f64, f64)> = v
                .iter()
                .enumerate()
                .filter_map(|(i, y)| y.filter(|y| y.is_finite() && *y > 0.0).map(|y| ((i + 1) as f64, y)))
                .collect();
            chart.draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(1)))?;
            chart.draw_series(pts.iter().map(|p| Circle::new(*p, 3, color.filled())))?;
            let ly = MT as i32 + 8 + 16 * k as i32;
            let lx = (W - MR - legend_w) as i32 + 12;
            root.draw(&PathElement::new(vec![(lx, ly), (lx + 14, ly)], color.stroke_width(3)))?;
            root.draw(&Text::new(
                label.clone(),
                (lx + 18, ly),
                anchored(font(11.0), HPos::Left, VPos::Center),
            ))?;
        }
        root.draw(&Text::new(title.to_string(), (ML as i32, 4), title_font(13.0)))?;
        Ok(())
    })
}

/// Points with optional error bars, for [`xy_chart`].
pub struct XyPoints<'a> {
    pub x: &'a [f64],
    pub y: &'a [f64],
    /// Half-length of the error bar per point (e.g. 2 standard errors).
    pub err: Option<&'a [f64]>,
    pub color: &'a str,
    pub label: &'a str,
}

/// A polyline, for [`xy_chart`].
pub struct XyLine<'a> {
    pub x: &'a [f64],
    pub y: &'a [f64],
    pub color: &'a str,
    pub label: &'a str,
    pub dashed: bool,
}

/// An x-y chart of measured points (with error bars) and curves (fits, model maps).
pub fn xy_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[XyPoints<'_>],
    lines: &[XyLine<'_>],
) -> String {
    const W: f64 = 820.0;
    const H: f64 = 440.0;
    const MR: f64 = 20.0;
    const MT: f64 = 44.0;
    const MB: f64 = 42.0;
    let err = |p: &XyPoints<'_>, i: usize| p.err.and_then(|e| e.get(i)).copied().unwrap_or(0.0);
    let xs =
        points.iter().flat_map(|p| p.x.iter().copied()).chain(lines.iter().flat_map(|l| l.x.iter().copied()));
    let (x0, x1) = padded_range(xs);
    let ys = points
        .iter()
        .flat_map(|p| p.y.iter().enumerate().flat_map(move |(i, y)| [y + err(p, i), y - err(p, i)]))
        .chain(lines.iter().flat_map(|l| l.y.iter().copied()));
    let (y0, y1) = padded_range(ys);
    render(title, W, H, |root| {
        let mut chart = ChartBuilder::on(root)
            .margin_top(MT as i32)
            .margin_right(MR as i32)
            .x_label_area_size(MB as i32)
            .y_label_area_size(ML as i32)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        chart
            .configure_mesh()
            .x_labels(6)
            .y_labels(6)
            .x_label_formatter(&|v| tick_label(*v))
            .y_label_formatter(&|v| tick_label(*v))
            .bold_line_style(grey(0xee))
            .light_line_style(TRANSPARENT)
            .axis_style(grey(0x99))
            .label_style(font(11.0))
            .axis_desc_style(font(11.0))
            .x_desc(x_label)
            .y_desc(y_label)
            .draw()?;
        for l in lines {
            let pts: Vec<(f64, f64)> =
                l.x.iter()
                    .zip(l.y)
                    .filter(|(x, y)| x.is_finite() && y.is_finite())
                    .map(|(x, y)| (*x, *y))
                    .collect();
            let style = rgb(l.color).stroke_width(2);
            if l.dashed {
                chart.draw_series(DashedLineSeries::new(pts, 5, 4, style))?;
            } else {
                chart.draw_series(LineSeries::new(pts, style))?;
            }
        }
        for p in points {
            let color = rgb(p.color);
            for (i, (x, y)) in p.x.iter().zip(p.y).enumerate() {
                if !(x.is_finite() && y.is_finite()) {
                    continue;
                }
                let e = err(p, i);
                if e.is_finite() && e > 0.0 {
                    chart.draw_series(std::iter::once(PathElement::new(
                        vec![(*x, y + e), (*x, y - e)],
                        color,
                    )))?;
                }
                chart.draw_series(std::iter::once(Circle::new((*x, *y), 3, color.filled())))?;
            }
        }
        root.draw(&Text::new(title.to_string(), (ML as i32, 4), title_font(13.0)))?;
        let mut lx = ML;
        let legend = points
            .iter()
            .map(|p| (p.label, p.color, true))
            .chain(lines.iter().map(|l| (l.label, l.color, false)));
        for (label, color, dot) in legend.filter(|l| !l.0.is_empty()) {
            let x = lx as i32;
            if dot {
                root.draw(&Circle::new((x + 5, 31), 3, rgb(color).filled()))?;
            } else {
                root.draw(&PathElement::new(vec![(x, 31), (x + 12, 31)], rgb(color).stroke_width(2)))?;
            }
            root.draw(&Text::new(
                label.to_string(),
                (x + 16, 31),
                anchored(font(11.0), HPos::Left, VPos::Center),
            ))?;
            lx += 28.0 + 6.5 * label.chars().count() as f64;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn envelope_keeps_spikes_and_bounds_point_count() {
        let n = 70_000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let mut y = vec![0.0; n];
        y[31_234] = 100.0;
        let pts = envelope(&t, &y, 800);
        assert!(pts.len() <= 2 * 800 + 2);
        assert!(pts.contains(&(31.234, 100.0)));
        // And the chart itself: one polyline of at most ~2 points per pixel column.
        let c =
            line_chart("long", "N m", &t, &[Series { values: &y, color: "#1f77b4", label: "x" }], &[], 300.0);
        let line = c.split("<polyline").find(|p| p.contains(r##"stroke="#1F77B4""##)).unwrap();
        let pts = line.split("points=\"").nth(1).unwrap().split('"').next().unwrap();
        assert!(pts.split_whitespace().count() <= 2 * 900, "{}", pts.split_whitespace().count());
        assert!(c.len() < 60_000, "{}", c.len());
    }

    #[test]
    fn charts_are_well_formed_with_odd_data() {
        let t = [0.0, 1.0, 2.0];
        let y = [f64::NAN, f64::NAN, f64::NAN];
        let c = line_chart(
            "a<b",
            "N m",
            &t,
            &[Series { values: &y, color: "#000", label: "x" }],
            &[(0.5, 1.5)],
            200.0,
        );
        assert!(c.starts_with("<svg") && c.ends_with("</svg>"));
        assert!(c.contains("a&lt;b") && !c.contains("NaN") && !c.contains("<script"));
        assert!(c.contains(r#"role="img""#) && c.contains(">time [s]<"));
        let b = budget_chart("t", &[Bar { label: "forward / steady", error: 0.7, samples: 0.2 }]);
        assert!(b.contains("70 % / 20 %") && b.contains(">forward / steady<"));
        assert_eq!(rgb("#1f77b4"), RGBColor(0x1f, 0x77, 0xb4));
        assert_eq!(rgb("#888"), RGBColor(0x88, 0x88, 0x88));
        assert_eq!(rgb("red"), BLACK);
    }

    #[test]
    fn xy_chart_draws_points_error_bars_and_lines() {
        let svg = xy_chart(
            "a<b",
            "x",
            "y",
            &[XyPoints {
                x: &[1.0, 2.0, 3.0],
                y: &[3.0, f64::NAN, 2.0],
                err: Some(&[0.5, 0.5, f64::NAN]),
                color: "#000",
                label: "p",
            }],
            &[XyLine { x: &[0.0, 3.0], y: &[0.0, 4.0], color: "#f00", label: "fit", dashed: true }],
        );
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>") && svg.contains("a&lt;b"));
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
        // Two finite points, one error bar, one dashed line, and the legend's dot.
        assert_eq!(svg.matches("<circle").count(), 3);
        assert_eq!(svg.matches(r##"<polyline fill="none" opacity="1" stroke="#000000""##).count(), 1);
        assert!(svg.matches(r##"stroke="#FF0000""##).count() > 3 && svg.contains(">fit<"));
        // Nothing to draw: still well formed.
        let e = xy_chart("t", "x", "y", &[], &[]);
        assert!(e.ends_with("</svg>") && !e.contains("NaN"));
        assert_eq!(
            (tick_label(-100.0), tick_label(2.5), tick_label(0.0)),
            ("-100".into(), "2.5".into(), "0".into())
        );
    }

    #[test]
    fn history_chart_draws_every_point_on_a_log_axis() {
        let series = vec![
            ("I_DC".to_string(), vec![Some(1.4), Some(0.3), Some(0.29)]),
            ("C_Kistler_L".to_string(), vec![Some(1.1), None, Some(f64::NAN)]),
        ];
        let c = history_chart("NRMSE per iteration", "NRMSE [%]", &series);
        assert!(c.starts_with("<svg") && c.ends_with("</svg>"));
        assert_eq!(c.matches("<circle").count(), 4);
        assert!(c.contains(">I_DC<") && c.contains(">0.1<") && c.contains(">1<") && c.contains(">2<"));
        assert!(c.contains(">3<") && !c.contains(">4<"));
        assert!(!c.contains("NaN") && !c.contains("inf"));
        // One iteration, no values: still well formed.
        let c = history_chart("t", "y", &[("a".to_string(), vec![None])]);
        assert!(c.ends_with("</svg>") && !c.contains("NaN"));
    }
}
