//! SVG plots of every result Tribo writes (plotters, SVG backend) and the files written with
//! them.
//!
//! # Style guide
//!
//! Every plot follows these rules, the conventions a matplotlib user expects; `tests/plots.rs`
//! reads each SVG back and checks them.
//! - **One colour and one dash pattern per series**, [`series_style`]: the ten-colour palette
//!   (matplotlib's `tab10`) together with four dash patterns (solid, long dash, short dash,
//!   dotted), cycled so that no two of the first 40 series share both; a set keeps its style
//!   (its position in the comparison) across every plot of a result set.
//! - **Legends in a box beside the plot**, never over the data (`legend_beside`); each entry
//!   drawn as its series is (colour, dash, marker, fill), so a swatch always matches its line.
//! - **Fills**: stacked areas are opaque tints; confidence bands are translucent and have their
//!   own legend entry drawn with the same fill and opacity.
//! - **Measured points** are black circles with error bars of one standard deviation wherever the
//!   data declare their noise (`# noise_nm:`), the legend saying so.
//! - **Axes**: units in parentheses in every axis title; shares and fractions from 0; no `-0`
//!   tick label (`tick_label`).
//! - **Titles** say what is plotted and for what: the rig, the law set, the speed; a plot of
//!   one piston is not titled as a mean over an engine's pistons.
//! - Curves that coincide are told apart by their dash patterns and named as coincident in
//!   the legend (`same torques as ...`).

use std::path::Path;

use plotters::coord::ranged1d::Ranged;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::output::OutputError;
use crate::study::Comparison;

type PlotResult = Result<(), Box<dyn std::error::Error>>;

/// The series palette: matplotlib's `tab10`, in its order.
pub const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// The dash patterns, (dash, gap) in pixels; `None` is a solid line. Dash lengths differ by
/// at least a factor of two, so they read apart at a glance (and in the tests' read-back).
pub const DASHES: [Option<(u32, u32)>; 4] = [None, Some((14, 6)), Some((6, 4)), Some((2, 4))];

/// How far a stacked area's fill is lightened towards white (opaque, [`tint`]).
const AREA_TINT: f64 = 0.3;

/// Opacity of a confidence band's fill (and of its legend swatch).
pub const BAND_OPACITY: f64 = 0.15;

/// How one series is drawn: its colour and dash pattern.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SeriesStyle {
    /// The line's colour.
    pub color: RGBColor,
    /// (dash, gap) in pixels, `None` solid.
    pub dash: Option<(u32, u32)>,
}

/// The style of series `k`: colour `k mod 10`, and a dash pattern that moves on with the
/// colour and shifts by three patterns per round of the palette, so series 0..40 all differ
/// in (colour, dash) and neighbours differ in both (also across a round's end).
pub fn series_style(k: usize) -> SeriesStyle {
    let c = k % PALETTE.len();
    let d = (c + 3 * (k / PALETTE.len())) % DASHES.len();
    SeriesStyle {
        color: PALETTE[c],
        dash: DASHES[d],
    }
}

/// `color` lightened towards white by `f` (0: itself, 1: white), opaque: the fill of a
/// stacked area and of its swatch, identical in both.
fn tint(color: RGBColor, f: f64) -> RGBColor {
    let lift = |c: u8| (c as f64 + (255.0 - c as f64) * f).round() as u8;
    RGBColor(lift(color.0), lift(color.1), lift(color.2))
}

/// Draw `pts` as one line in `style`, `width` pixels wide.
fn draw_styled<X, Y>(
    chart: &mut ChartContext<'_, SVGBackend<'_>, Cartesian2d<X, Y>>,
    pts: Vec<(f64, f64)>,
    style: SeriesStyle,
    width: u32,
) -> PlotResult
where
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let stroke = style.color.stroke_width(width);
    match style.dash {
        None => chart.draw_series(LineSeries::new(pts, stroke))?,
        Some((on, off)) => {
            chart.draw_series(DashedLineSeries::new(pts, on as i32, off as i32, stroke))?
        }
    };
    Ok(())
}

pub(crate) fn io(e: impl std::fmt::Display) -> std::io::Error {
    std::io::Error::other(e.to_string())
}

/// `torque_vs_speed.svg` of `compare`: each set's torque against the measured points.
pub fn torque_svg(c: &Comparison) -> std::io::Result<String> {
    svg(|s| torque_plot(c, s))
}

/// `contributions_<set>.svg` of `compare`: the joints' shares of one set's torque.
pub fn contributions_svg(set: &crate::study::SetResult) -> std::io::Result<String> {
    svg(|s| contributions_plot(set, s))
}

/// `piston_regimes.svg` of `compare`: the pistons' lubrication regimes per set.
pub fn regimes_svg(c: &Comparison) -> std::io::Result<String> {
    svg(|s| regimes_plot(c, s))
}

/// `sweep_<set>.svg` of `sweep`: one set's torque over oil temperature and speed.
pub fn sweep_svg(s: &crate::study::Sweep, set: &crate::study::SweepSet) -> std::io::Result<String> {
    svg(|o| sweep_plot(s, set, o))
}

/// Label, speeds, Tribo's values and the correlation's (each `None` where it has none): one
/// line pair of [`correlation_svg`].
pub(crate) type Series = (String, Vec<f64>, Vec<Option<f64>>, Vec<Option<f64>>);

/// A rendered file's text, or the error naming the file.
fn rendered<T>(what: &str, r: std::io::Result<T>) -> Result<T, OutputError> {
    r.map_err(|error| OutputError::Render {
        what: what.to_string(),
        error,
    })
}

fn svg(draw: impl FnOnce(&mut String) -> PlotResult) -> std::io::Result<String> {
    let mut s = String::new();
    draw(&mut s).map_err(io)?;
    Ok(s)
}

type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A titled chart with labelled axes (units in the labels) on `root`.
fn frame<'a, 'b>(
    root: &'a DrawingArea<SVGBackend<'b>, plotters::coord::Shift>,
    caption: &str,
    x: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
    x_desc: &str,
    y_desc: &str,
) -> Result<Chart<'a, 'b>, Box<dyn std::error::Error>> {
    root.fill(&WHITE)?;
    // Tick labels with one decimal more than a tenth of the axis needs, never `-0`.
    let y_decimals = decimals_for(y.end - y.start);
    let mut chart = ChartBuilder::on(root)
        .caption(caption, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(x, y)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .x_label_formatter(&|x| tick_label(*x, 2))
        .y_label_formatter(&|y| tick_label(*y, y_decimals))
        .y_desc(y_desc)
        .draw()?;
    Ok(chart)
}

/// Decimals a tick label needs on an axis spanning `span`: one more than a tenth of the span.
fn decimals_for(span: f64) -> usize {
    if !(span.is_finite() && span > 0.0) {
        return 2;
    }
    (1.0 - (span / 10.0).log10().floor()).clamp(0.0, 12.0) as usize
}

/// A tick label: `v` with `decimals`, trailing zeros dropped, and never `-0` (a tick at zero
/// computed as -1e-17 is zero).
pub(crate) fn tick_label(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" {
        "0".into()
    } else {
        s
    }
}

/// The largest magnitude an axis reaches. Values beyond it (a law or a data file gone wild)
/// are clipped to it when choosing the range, so the axis, its ticks and labels stay finite and
/// are computed in bounded time.
pub const AXIS_LIMIT: f64 = 1e9;

/// An axis range covering the finite `values` (clipped to [`AXIS_LIMIT`]), widened by `pad`
/// times the span on each side. Non-finite values are skipped; no finite value gives `0..1`.
/// The result is always finite with `lo < hi`.
pub(crate) fn range(values: impl Iterator<Item = f64>, pad: f64) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .map(|v| v.clamp(-AXIS_LIMIT, AXIS_LIMIT))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    // A span that resolves at least 1e-6 of the values' magnitude (1e-6 absolute near zero).
    let span = (hi - lo).max(1e-6 * lo.abs().max(hi.abs()).max(1.0));
    let pad = if pad.is_finite() {
        pad.clamp(0.0, 1.0)
    } else {
        0.0
    };
    (lo - pad * span, hi + pad * span)
}

fn torque_plot(c: &Comparison, out: &mut String) -> PlotResult {
    let noise = c.noise_nm.filter(|n| n.is_finite() && *n > 0.0);
    let mut entries: Vec<(String, Swatch)> = vec![(
        match noise {
            Some(n) => format!("measured\nbars: noise +/-{n} N m (1 sigma)"),
            None => "measured\n(the data declare no noise)".into(),
        },
        Swatch::Measured {
            error_bar: noise.is_some(),
        },
    )];
    for (i, s) in c.sets.iter().enumerate() {
        let style = series_style(i);
        let loo = s
            .scores
            .cv_rmse_nm
            .map_or("-".to_string(), |v| format!("{v:.3}"));
        let status = match s.calibration.status {
            crate::study::CalibrationStatus::NotFitted => ", not fitted",
            _ => "",
        };
        let mut label = format!(
            "{}\nRMSE {:.3} N m, LOO {loo} N m{status}",
            s.lawset, s.rmse_nm
        );
        if let Some(t) = s.tie.as_ref().filter(|t| t.same_torques) {
            label.push_str(&format!("\nsame torques as {}", t.with.join(", ")));
        }
        entries.push((label, Swatch::Marked(style, i)));
        if s.band_lower_nm.is_some() {
            entries.push((
                format!("{}: 95% band", s.lawset),
                Swatch::Fill(style.color, BAND_OPACITY),
            ));
        }
    }
    let labels: Vec<String> = entries.iter().map(|e| e.0.clone()).collect();
    let height = legend_height(&labels).max(560);
    let root = SVGBackend::with_string(out, (1100, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let (plot, side) = root.split_horizontally(1100 - legend_width(&labels));
    let speeds: Vec<f64> = c.data.iter().map(|d| d.speed_rpm).collect();
    let (x0, x1) = range(speeds.iter().copied(), 0.05);
    // The bands and error bars are part of the picture: the axis reaches their edges too.
    let all = c
        .data
        .iter()
        .map(|d| d.torque_nm + noise.unwrap_or(0.0))
        .chain(
            c.sets
                .iter()
                .flat_map(|s| s.run.plateaus.iter().map(|p| p.motoring_torque_nm)),
        )
        .chain(
            c.sets
                .iter()
                .flat_map(|s| s.band_upper_nm.iter().flatten().copied()),
        );
    let (y0, y1) = range(all, 0.1);
    let y0 = y0.min(0.0);
    let mut chart = frame(
        &plot,
        &format!("Motoring torque vs crank speed: {} ({})", c.rig, c.mode),
        x0..x1,
        y0..y1,
        "crank speed (rpm)",
        "motoring torque (N m)",
    )?;
    // The 95% bands first, translucent, so the measurements and lines stay visible on top.
    for (i, s) in c.sets.iter().enumerate() {
        let color = series_style(i).color;
        if let (Some(lo), Some(hi)) = (&s.band_lower_nm, &s.band_upper_nm) {
            let mut poly: Vec<(f64, f64)> = Vec::new();
            for (p, h) in s.run.plateaus.iter().zip(hi) {
                poly.push((p.set_speed_rpm, h.min(y1)));
            }
            for (p, l) in s.run.plateaus.iter().zip(lo).rev() {
                poly.push((p.set_speed_rpm, l.max(y0)));
            }
            chart.draw_series(std::iter::once(Polygon::new(
                poly,
                color.mix(BAND_OPACITY).filled(),
            )))?;
        }
    }
    for (i, s) in c.sets.iter().enumerate() {
        let style = series_style(i);
        let pts: Vec<(f64, f64)> = s
            .run
            .plateaus
            .iter()
            .map(|p| (p.set_speed_rpm, p.motoring_torque_nm))
            .collect();
        draw_styled(&mut chart, pts.clone(), style, 2)?;
        draw_markers(&mut chart, i, &pts, style.color)?;
    }
    if let Some(n) = noise {
        // One standard deviation either side, with caps.
        chart.draw_series(c.data.iter().map(|d| {
            let (x, y) = (d.speed_rpm, d.torque_nm);
            PathElement::new(vec![(x, y - n), (x, y + n)], BLACK.stroke_width(1))
        }))?;
        let cap = 0.006 * (x1 - x0);
        chart.draw_series(c.data.iter().flat_map(|d| {
            let (x, y) = (d.speed_rpm, d.torque_nm);
            [y - n, y + n].map(|yy| {
                PathElement::new(vec![(x - cap, yy), (x + cap, yy)], BLACK.stroke_width(1))
            })
        }))?;
    }
    chart.draw_series(
        c.data
            .iter()
            .map(|d| Circle::new((d.speed_rpm, d.torque_nm), 4, BLACK.filled())),
    )?;
    legend_beside(&side, "law set", &entries)?;
    root.present()?;
    Ok(())
}

fn contributions_plot(set: &crate::study::SetResult, out: &mut String) -> PlotResult {
    let root = SVGBackend::with_string(out, (1000, 560)).into_drawing_area();
    root.fill(&WHITE)?;
    let p = &set.run.plateaus;
    let n_laws = p.first().map_or(0, |x| x.joints.len());
    let labels: Vec<String> = (0..n_laws)
        .map(|k| {
            p.first()
                .map(|x| format!("{} ({})", x.joints[k].joint, x.joints[k].law))
                .unwrap_or_default()
        })
        .collect();
    // The legend gets its own column right of the plot, so it can never cover a stack.
    let (plot, side) = root.split_horizontally(1000 - legend_width(&labels));
    let speeds: Vec<f64> = p.iter().map(|x| x.set_speed_rpm).collect();
    let (x0, x1) = range(speeds.iter().copied(), 0.02);
    let totals: Vec<f64> = p
        .iter()
        .map(|x| x.joints.iter().map(|j| j.friction_torque_nm.max(0.0)).sum())
        .collect();
    let (_, y1) = range(totals.iter().copied().chain([0.0]), 0.1);
    let mut chart = frame(
        &plot,
        &format!("Friction torque by joint and law: {}", set.lawset),
        x0..x1,
        0.0..y1,
        "crank speed (rpm)",
        "friction torque at the crank (N m)",
    )?;
    // Stack: draw the cumulative sums from the top down so each band shows its own share.
    for k in (0..n_laws).rev() {
        let color = series_style(k).color;
        let pts: Vec<(f64, f64)> = p
            .iter()
            .map(|x| {
                (
                    x.set_speed_rpm,
                    x.joints[..=k]
                        .iter()
                        .map(|j| j.friction_torque_nm.max(0.0))
                        .sum(),
                )
            })
            .collect();
        chart.draw_series(
            AreaSeries::new(pts, 0.0, tint(color, AREA_TINT).filled()).border_style(color),
        )?;
    }
    // Listed top down in the order the bands are stacked (topmost band first).
    let entries: Vec<(String, Swatch)> = (0..n_laws)
        .rev()
        .map(|k| {
            let fill = tint(series_style(k).color, AREA_TINT);
            (labels[k].clone(), Swatch::Fill(fill, 1.0))
        })
        .collect();
    legend_beside(&side, "joint (law)", &entries)?;
    root.present()?;
    Ok(())
}

fn regimes_plot(c: &Comparison, out: &mut String) -> PlotResult {
    let root = SVGBackend::with_string(out, (1000, 560)).into_drawing_area();
    root.fill(&WHITE)?;
    let names = ["boundary", "mixed", "hydrodynamic"];
    let labels: Vec<String> = c
        .sets
        .iter()
        .flat_map(|s| names.iter().map(move |n| format!("{}: {n}", s.lawset)))
        .collect();
    // The legend in its own column beside the plot, never over the curves.
    let (plot, side) = root.split_horizontally(1000 - legend_width(&labels));
    let speeds: Vec<f64> = c.data.iter().map(|d| d.speed_rpm).collect();
    let (x0, x1) = range(speeds.iter().copied(), 0.02);
    // A share runs from 0 to 1: the axis starts at 0 (a share of 0 is drawn on it, its markers
    // visible) and ends a little above 1.
    let pistons = c
        .sets
        .iter()
        .filter_map(|s| s.run.plateaus.first())
        .map(|p| {
            p.joints
                .iter()
                .filter(|j| is_piston(&j.joint))
                .map(|j| &j.joint)
        })
        .map(|js| {
            let mut v: Vec<_> = js.collect();
            v.dedup();
            v.len()
        })
        .max()
        .unwrap_or(0);
    let title = if pistons > 1 {
        format!(
            "Piston lubrication regime vs crank speed: {}, mean over its {pistons} pistons",
            c.rig
        )
    } else {
        format!("Piston lubrication regime vs crank speed: {}", c.rig)
    };
    let mut chart = frame(
        &plot,
        &title,
        x0..x1,
        0.0..1.06,
        "crank speed (rpm)",
        "share of the cycle in the regime (-)",
    )?;
    let mut entries: Vec<(String, Swatch)> = Vec::new();
    let series: Vec<Vec<(f64, [f64; 3])>> = c.sets.iter().map(piston_regimes).collect();
    for (i, (s, piston)) in c.sets.iter().zip(&series).enumerate() {
        if piston.is_empty() {
            continue;
        }
        // Sets with the same shares draw one over the other: the legend says so.
        let same: Vec<&str> = c
            .sets
            .iter()
            .zip(&series)
            .enumerate()
            .filter(|(k, (_, other))| *k != i && *other == piston)
            .map(|(_, (o, _))| o.lawset.as_str())
            .collect();
        // One colour per law set, one dash pattern and marker per regime.
        let color = series_style(i).color;
        for (r, name) in names.iter().enumerate() {
            let style = SeriesStyle {
                color,
                dash: DASHES[r],
            };
            let pts: Vec<(f64, f64)> = piston.iter().map(|(v, sh)| (*v, sh[r])).collect();
            draw_styled(&mut chart, pts.clone(), style, 2)?;
            draw_markers(&mut chart, r, &pts, color)?;
            let mut label = format!("{}: {name}", s.lawset);
            if r == 0 && !same.is_empty() {
                label.push_str(&format!("\nsame shares as {}", same.join(", ")));
            }
            entries.push((label, Swatch::Marked(style, r)));
        }
    }
    if entries.is_empty() {
        chart.draw_series(std::iter::once(Text::new(
            "no law set reports a piston regime",
            (x0 + 0.05 * (x1 - x0), 0.5),
            ("sans-serif", 18),
        )))?;
    }
    legend_beside(&side, "law set: regime", &entries)?;
    root.present()?;
    Ok(())
}

/// Each plateau's speed (rpm) and the piston's boundary, mixed and hydrodynamic shares: the
/// single cylinder's piston, or the mean over an engine's pistons (`piston_k`).
fn piston_regimes(s: &crate::study::SetResult) -> Vec<(f64, [f64; 3])> {
    s.run
        .plateaus
        .iter()
        .filter_map(|p| {
            let shares: Vec<_> = p
                .joints
                .iter()
                .filter(|j| is_piston(&j.joint))
                .filter(|j| j.regime_share.none < 0.5)
                .map(|j| j.regime_share)
                .collect();
            let n = shares.len() as f64;
            (n > 0.0).then(|| {
                let mean =
                    |f: fn(&crate::sim::RegimeShare) -> f64| shares.iter().map(f).sum::<f64>() / n;
                (
                    p.set_speed_rpm,
                    [
                        mean(|r| r.boundary),
                        mean(|r| r.mixed),
                        mean(|r| r.hydrodynamic),
                    ],
                )
            })
        })
        .collect()
}

/// Torque change against scale factor, one line per law set and speed (SVG text), the legend
/// beside the plot.
pub fn mass_sweep_svg(r: &[crate::study::MassResponse]) -> std::io::Result<String> {
    svg(|out| {
        let mut lines: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
        for set in r {
            let mut speeds: Vec<f64> = set.changes.iter().map(|c| c.speed_rpm).collect();
            speeds.sort_by(f64::total_cmp);
            speeds.dedup();
            for sp in speeds {
                let mut pts: Vec<(f64, f64)> = set
                    .changes
                    .iter()
                    .filter(|c| c.speed_rpm == sp)
                    .map(|c| (c.scale, c.change_nm))
                    .collect();
                pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                lines.push((format!("{} {:.0} rpm", set.lawset, sp), pts));
            }
        }
        let labels: Vec<String> = lines.iter().map(|l| l.0.clone()).collect();
        let height = legend_height(&labels).max(560);
        let root = SVGBackend::with_string(out, (1000, height)).into_drawing_area();
        root.fill(&WHITE)?;
        let (plot, side) = root.split_horizontally(1000 - legend_width(&labels));
        let all = r.iter().flat_map(|s| s.changes.iter());
        let (x0, x1) = range(all.clone().map(|c| c.scale), 0.03);
        let (y0, y1) = range(all.map(|c| c.change_nm).chain([0.0]), 0.1);
        let body = r
            .first()
            .map(|s| format!("{:?}", s.body).to_lowercase())
            .unwrap_or_default();
        let mut chart = frame(
            &plot,
            &format!("Motoring torque change vs {body} mass scale, by law set and speed"),
            x0..x1,
            y0..y1,
            &format!("{body} mass scale (-)"),
            "torque change (N m)",
        )?;
        let mut entries = Vec::new();
        for (k, (label, pts)) in lines.into_iter().enumerate() {
            let style = series_style(k);
            draw_styled(&mut chart, pts, style, 2)?;
            entries.push((label, Swatch::Line(style)));
        }
        legend_beside(&side, "law set, speed", &entries)?;
        root.present()?;
        Ok(())
    })
}

/// How a legend entry is drawn: as its series is, so swatch and line always match.
#[derive(Clone, Copy)]
enum Swatch {
    /// A line in its series' style.
    Line(SeriesStyle),
    /// A filled box: the colour and its opacity (1 for a stacked area's opaque tint).
    Fill(RGBColor, f64),
    /// A line with the marker number `k` of [`draw_markers`] on it.
    Marked(SeriesStyle, usize),
    /// A measured point: a black circle, with an error bar when the data declare their noise.
    Measured { error_bar: bool },
}

/// Marker shapes in the order [`marker`] uses them.
const MARKERS: usize = 5;

/// Marker number `k` (circle, triangle, square, diamond, cross, then again) at each of
/// `pts`, in `color`: with the colours, it tells lines apart in print and for readers who do
/// not see colour.
fn draw_markers(
    chart: &mut Chart<'_, '_>,
    k: usize,
    pts: &[(f64, f64)],
    color: RGBColor,
) -> PlotResult {
    let style = color.filled();
    let at = pts.iter().map(|q| EmptyElement::at(*q));
    match k % MARKERS {
        0 => chart.draw_series(at.map(|e| e + Circle::new((0, 0), 4, style)))?,
        1 => chart.draw_series(at.map(|e| e + TriangleMarker::new((0, 0), 5, style)))?,
        2 => chart.draw_series(at.map(|e| e + Rectangle::new([(-4, -4), (4, 4)], style)))?,
        3 => chart.draw_series(
            at.map(|e| e + Polygon::new(vec![(0, -5), (5, 0), (0, 5), (-5, 0)], style)),
        )?,
        _ => chart.draw_series(at.map(|e| e + Cross::new((0, 0), 4, color.stroke_width(2))))?,
    };
    Ok(())
}

/// [`draw_markers`]'s marker `k` at pixel `at` of `area` (a legend).
fn draw_marker_px(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    k: usize,
    at: (i32, i32),
    color: RGBColor,
) -> PlotResult {
    let style = color.filled();
    let e = EmptyElement::at(at);
    match k % MARKERS {
        0 => area.draw(&(e + Circle::new((0, 0), 4, style)))?,
        1 => area.draw(&(e + TriangleMarker::new((0, 0), 5, style)))?,
        2 => area.draw(&(e + Rectangle::new([(-4, -4), (4, 4)], style)))?,
        3 => area.draw(&(e + Polygon::new(vec![(0, -5), (5, 0), (0, 5), (-5, 0)], style)))?,
        _ => area.draw(&(e + Cross::new((0, 0), 4, color.stroke_width(2))))?,
    };
    Ok(())
}

/// Width in pixels of a legend column for `labels` (each maybe several lines) at 14 px
/// sans-serif, with its swatch and box.
fn legend_width(labels: &[String]) -> u32 {
    let chars = labels
        .iter()
        .flat_map(|l| l.lines())
        .map(|l| l.chars().count())
        .max()
        .unwrap_or(0) as u32;
    (chars * 8 + 64).clamp(100, 380)
}

/// Height in pixels a [`legend_beside`] of `entries` needs, so a plot can grow to hold it.
fn legend_height(labels: &[String]) -> u32 {
    let lines: usize = labels.iter().map(|l| l.lines().count().max(1)).sum();
    (30 + 34 + 20 * lines + 6 * labels.len() + 30) as u32
}

/// Draw a swatch with its middle at pixel (`x`, `y`) of `area`, 24 pixels wide.
fn draw_swatch(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    swatch: Swatch,
    (x, y): (i32, i32),
) -> PlotResult {
    match swatch {
        Swatch::Line(s) | Swatch::Marked(s, _) => {
            let stroke = s.color.stroke_width(2);
            match s.dash {
                None => area.draw(&PathElement::new(vec![(x, y), (x + 24, y)], stroke))?,
                Some((on, off)) => area.draw(&plotters::element::DashedPathElement::new(
                    vec![(x, y), (x + 24, y)],
                    on as i32,
                    off as i32,
                    stroke,
                ))?,
            }
            if let Swatch::Marked(_, k) = swatch {
                draw_marker_px(area, k, (x + 12, y), s.color)?;
            }
        }
        Swatch::Fill(c, opacity) => area.draw(&Rectangle::new(
            [(x, y - 6), (x + 24, y + 6)],
            c.mix(opacity).filled(),
        ))?,
        Swatch::Measured { error_bar } => {
            if error_bar {
                area.draw(&PathElement::new(
                    vec![(x + 12, y - 8), (x + 12, y + 8)],
                    BLACK,
                ))?;
                for yy in [y - 8, y + 8] {
                    area.draw(&PathElement::new(vec![(x + 8, yy), (x + 16, yy)], BLACK))?;
                }
            }
            area.draw(&Circle::new((x + 12, y), 4, BLACK.filled()))?;
        }
    }
    Ok(())
}

/// The legend: in its own area beside the plot (never over the data), in a box, a title and
/// then one swatch and label per entry, top down; a label may run over several lines.
fn legend_beside(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    title: &str,
    entries: &[(String, Swatch)],
) -> PlotResult {
    area.fill(&WHITE)?;
    let (w, _) = area.dim_in_pixel();
    let (x0, top) = (10_i32, 30_i32);
    let lines: i32 = entries
        .iter()
        .map(|(l, _)| l.lines().count().max(1) as i32)
        .sum();
    let bottom = top + 34 + 20 * lines + 6 * entries.len() as i32;
    area.draw(&Rectangle::new(
        [(2, top), (w as i32 - 4, bottom)],
        BLACK.stroke_width(1),
    ))?;
    area.draw(&Text::new(
        title.to_string(),
        (x0, top + 8),
        ("sans-serif", 15),
    ))?;
    let mut y = top + 44;
    for (label, swatch) in entries {
        draw_swatch(area, *swatch, (x0, y))?;
        for (i, line) in label.lines().enumerate() {
            let size = if i == 0 { 14 } else { 12 };
            area.draw(&Text::new(
                line.to_string(),
                (x0 + 32, y - 7 + 20 * i as i32),
                ("sans-serif", size),
            ))?;
        }
        y += 20 * label.lines().count().max(1) as i32 + 6;
    }
    Ok(())
}

/// Colour of temperature `k` of `n`: along a cold-to-hot scale (blue, teal, ochre, orange, dark
/// red), so the lines read as temperatures and neighbours stay distinguishable.
fn temperature_color(k: usize, n: usize) -> RGBColor {
    const STOPS: [(f64, f64, f64); 5] = [
        (33.0, 102.0, 172.0),
        (27.0, 158.0, 119.0),
        (200.0, 160.0, 0.0),
        (230.0, 97.0, 1.0),
        (165.0, 0.0, 38.0),
    ];
    let f = if n > 1 {
        k as f64 / (n - 1) as f64
    } else {
        0.0
    };
    let x = f * (STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let u = x - i as f64;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    let mix = |p: f64, q: f64| (p + (q - p) * u).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// File-name-safe form of a law-set name (letters, digits, `-`, `_`, `.`; anything else `_`).
pub fn file_stem(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Torque vs speed of one law set of a sweep, one line per oil temperature, legend in C beside
/// the plot.
fn sweep_plot(
    s: &crate::study::Sweep,
    set: &crate::study::SweepSet,
    out: &mut String,
) -> PlotResult {
    let root = SVGBackend::with_string(out, (960, 560)).into_drawing_area();
    root.fill(&WHITE)?;
    let labels: Vec<String> = s.temps_c.iter().map(|t| format!("{t} C")).collect();
    let title = "oil temperature";
    let width = legend_width(&[labels.as_slice(), &[title.to_string()]].concat());
    let (plot, side) = root.split_horizontally(960 - width);
    let (x0, x1) = range(s.speeds_rpm.iter().copied(), 0.05);
    let (y0, y1) = range(set.points.iter().map(|p| p.torque_nm).chain([0.0]), 0.1);
    // From zero unless a torque is negative (a law set that drives the crank).
    let y0 = if set.points.iter().any(|p| p.torque_nm < 0.0) {
        y0
    } else {
        0.0
    };
    let mut chart = frame(
        &plot,
        &format!(
            "Motoring torque vs crank speed by oil temperature: {}, {}",
            s.rig, set.lawset
        ),
        x0..x1,
        y0..y1,
        "crank speed (rpm)",
        "motoring torque (N m)",
    )?;
    let n = s.speeds_rpm.len();
    let mut entries = Vec::new();
    for (k, label) in labels.iter().enumerate() {
        // Colour along the cold-to-hot scale, and a dash pattern of its own.
        let style = SeriesStyle {
            color: temperature_color(k, s.temps_c.len()),
            dash: DASHES[k % DASHES.len()],
        };
        let mut pts: Vec<(f64, f64)> = (0..n)
            .map(|i| (s.speeds_rpm[i], set.torque(k, i, n)))
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        draw_styled(&mut chart, pts.clone(), style, 2)?;
        draw_markers(&mut chart, k, &pts, style.color)?;
        entries.push((label.clone(), Swatch::Marked(style, k)));
    }
    legend_beside(&side, title, &entries)?;
    root.present()?;
    Ok(())
}

/// The SVG of `tribo plot-law`: a law's force (or torque) against sliding velocity through
/// zero (top), and its magnitude against sliding speed on a logarithmic axis for the
/// low-speed detail (bottom); one line per load and oil temperature (blues cold, reds hot,
/// darker for heavier loads), legend beside the plots.
pub fn law_plot_svg(c: &crate::check::LawCurves) -> std::io::Result<String> {
    svg(|s| law_plot(c, s))
}

/// Write [`law_plot_svg`] to `path` atomically (a temporary file beside it, renamed into
/// place).
pub fn write_law_plot(c: &crate::check::LawCurves, path: &Path) -> Result<(), OutputError> {
    let name = path.display().to_string();
    let text = rendered(&name, law_plot_svg(c))?;
    crate::output::write_atomic(path, text.as_bytes())
}

/// Colour of a law-plot curve: temperature `t` of `nt` picks blues (cold) or reds (hot),
/// load `l` of `nl` its shade, darker for heavier.
fn law_curve_color(t: usize, nt: usize, l: usize, nl: usize) -> RGBColor {
    let base = temperature_color(if t + 1 == nt && nt > 1 { 4 } else { 0 }, 5);
    let f = if nl > 1 {
        0.55 - 0.55 * l as f64 / (nl - 1) as f64
    } else {
        0.0
    };
    let lift = |c: u8| (c as f64 + (255.0 - c as f64) * f).round() as u8;
    RGBColor(lift(base.0), lift(base.1), lift(base.2))
}

fn law_plot(c: &crate::check::LawCurves, out: &mut String) -> PlotResult {
    let (w, h) = (960_u32, 900_u32);
    let root = SVGBackend::with_string(out, (w, h)).into_drawing_area();
    root.fill(&WHITE)?;
    let temps: Vec<f64> = {
        let mut t: Vec<f64> = c.curves.iter().map(|k| k.oil_temp_c).collect();
        t.dedup();
        t
    };
    let loads: Vec<f64> = {
        let mut l: Vec<f64> = c.curves.iter().map(|k| k.load_n).collect();
        l.sort_by(f64::total_cmp);
        l.dedup();
        l
    };
    let labels: Vec<String> = c
        .curves
        .iter()
        .map(|k| format!("{} N, {} C", k.load_n, k.oil_temp_c))
        .collect();
    let title = "load, oil";
    let width = legend_width(&[labels.as_slice(), &[title.to_string()]].concat());
    let (plots, side) = root.split_horizontally(w - width);
    let (top, bottom) = plots.split_vertically(h / 2);
    let (quantity, unit) = match c.kind {
        crate::plugin_api::JointKind::Revolute => ("torque", "N m"),
        crate::plugin_api::JointKind::Prismatic => ("force", "N"),
    };
    let state_note = if c.stateful { ", steady sliding" } else { "" };
    // Cold curves are drawn wider, so a temperature-blind law's hot curve lies visibly on top.
    let stroke = |k: &crate::check::Curve| {
        if temps.first() == Some(&k.oil_temp_c) {
            4
        } else {
            2
        }
    };
    // Colour by temperature and load, a dash pattern per load.
    let style = |k: &crate::check::Curve| {
        let t = temps.iter().position(|x| *x == k.oil_temp_c).unwrap_or(0);
        let l = loads.iter().position(|x| *x == k.load_n).unwrap_or(0);
        SeriesStyle {
            color: law_curve_color(t, temps.len(), l, loads.len()),
            dash: DASHES[l % DASHES.len()],
        }
    };
    // Top: signed force through zero.
    let (x0, x1) = range(
        c.curves.iter().flat_map(|k| k.points.iter().map(|p| p.0)),
        0.02,
    );
    let (y0, y1) = range(
        c.curves
            .iter()
            .flat_map(|k| k.points.iter().map(|p| p.1))
            .chain([0.0]),
        0.08,
    );
    let mut chart = frame(
        &top,
        &format!(
            "{}: {quantity} vs sliding velocity, {} joint{state_note}",
            c.law, c.joint
        ),
        x0..x1,
        y0..y1,
        "sliding velocity at the contact (m/s)",
        &format!("friction {quantity} ({unit})"),
    )?;
    for k in &c.curves {
        let pts: Vec<(f64, f64)> = k
            .points
            .iter()
            .filter(|p| p.1.is_finite())
            .copied()
            .collect();
        draw_styled(&mut chart, pts, style(k), stroke(k))?;
    }
    // Bottom: magnitude against speed on a log axis (the Stribeck region near zero).
    let speeds = c
        .curves
        .iter()
        .flat_map(|k| k.speed_points.iter().map(|p| p.0))
        .filter(|v| *v > 0.0);
    let (s0, s1) = speeds.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let (s0, s1) = if s0.is_finite() && s1 > s0 {
        (s0, s1)
    } else {
        (1e-5, 1.0)
    };
    let (m0, m1) = range(
        c.curves
            .iter()
            .flat_map(|k| k.speed_points.iter().map(|p| p.1))
            .chain([0.0]),
        0.08,
    );
    bottom.fill(&WHITE)?;
    let mut log_chart = ChartBuilder::on(&bottom)
        .caption(
            format!("|{quantity}| vs sliding speed (logarithmic)"),
            ("sans-serif", 20),
        )
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d((s0..s1).log_scale(), 0.0f64.min(m0)..m1)?;
    log_chart
        .configure_mesh()
        .x_desc("sliding speed at the contact (m/s)")
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_desc(format!("|{quantity}| ({unit})"))
        .y_label_formatter(&|y| tick_label(*y, decimals_for(m1 - m0)))
        .draw()?;
    for k in &c.curves {
        let pts: Vec<(f64, f64)> = k
            .speed_points
            .iter()
            .filter(|p| p.0 > 0.0 && p.1.is_finite())
            .copied()
            .collect();
        draw_styled(&mut log_chart, pts, style(k), stroke(k))?;
    }
    let entries: Vec<(String, Swatch)> = c
        .curves
        .iter()
        .zip(&labels)
        .map(|(k, l)| (l.clone(), Swatch::Line(style(k))))
        .collect();
    legend_beside(&side, title, &entries)?;
    root.present()?;
    Ok(())
}

/// The FMEP breakdown of a run as lines: one line per component
/// (joint), in kPa, the basis in the caption (`run --fmep`: `fmep.svg`).
pub fn fmep_svg(r: &crate::sim::RunResult) -> std::io::Result<String> {
    svg(|s| fmep_plot(r, s))
}

fn fmep_plot(r: &crate::sim::RunResult, out: &mut String) -> PlotResult {
    let root = SVGBackend::with_string(out, (1000, 560)).into_drawing_area();
    root.fill(&WHITE)?;
    let p = &r.plateaus;
    let labels: Vec<String> = p
        .first()
        .map(|x| x.fmep.components.iter().map(|c| c.joint.clone()).collect())
        .unwrap_or_default();
    let mut legend_labels = labels.clone();
    legend_labels.push("total".into());
    let (plot, side) = root.split_horizontally(1000 - legend_width(&legend_labels));
    let speeds: Vec<f64> = p.iter().map(|x| x.set_speed_rpm).collect();
    let (x0, x1) = range(speeds.iter().copied(), 0.05);
    let values = p.iter().flat_map(|x| {
        x.fmep
            .components
            .iter()
            .map(|c| c.kpa)
            .chain([x.fmep.total_kpa])
    });
    let (y0, y1) = range(values.chain([0.0]), 0.08);
    let basis = match r.fmep.basis {
        crate::sim::FmepBasis::TwoStroke => "2 pi T / V_d",
        crate::sim::FmepBasis::FourStroke => "4 pi T / V_d",
    };
    let mut chart = frame(
        &plot,
        &format!("FMEP by component vs crank speed: {} ({basis})", r.rig),
        x0..x1,
        y0..y1,
        "crank speed (rpm)",
        "FMEP (kPa)",
    )?;
    for k in 0..labels.len() {
        let style = series_style(k);
        let pts: Vec<(f64, f64)> = p
            .iter()
            .filter_map(|x| x.fmep.components.get(k).map(|c| (x.set_speed_rpm, c.kpa)))
            .collect();
        draw_styled(&mut chart, pts, style, 2)?;
    }
    let total: Vec<(f64, f64)> = p
        .iter()
        .map(|x| (x.set_speed_rpm, x.fmep.total_kpa))
        .collect();
    chart.draw_series(LineSeries::new(total, BLACK.stroke_width(3)))?;
    let mut entries: Vec<(String, Swatch)> = labels
        .iter()
        .enumerate()
        .map(|(k, l)| (l.clone(), Swatch::Line(series_style(k))))
        .collect();
    entries.push((
        "total".into(),
        Swatch::Line(SeriesStyle {
            color: BLACK,
            dash: None,
        }),
    ));
    legend_beside(&side, "component", &entries)?;
    root.present()?;
    Ok(())
}

/// Friction torque at the crank of every joint (its laws summed) over one cycle of a plateau
/// (`run --crank-angle`).
pub fn friction_vs_angle_svg(t: &crate::sim::CrankAngleTrace) -> std::io::Result<String> {
    svg(|s| friction_vs_angle_plot(t, s))
}

fn friction_vs_angle_plot(t: &crate::sim::CrankAngleTrace, out: &mut String) -> PlotResult {
    let root = SVGBackend::with_string(out, (1000, 560)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut joints: Vec<String> = Vec::new();
    for (j, _) in &t.laws {
        if !joints.contains(j) {
            joints.push(j.clone());
        }
    }
    let series: Vec<Vec<(f64, f64)>> = joints
        .iter()
        .map(|j| {
            t.samples
                .iter()
                .map(|s| {
                    let sum: f64 = t
                        .laws
                        .iter()
                        .zip(&s.laws)
                        .filter(|((jj, _), _)| jj == j)
                        .map(|(_, l)| l.friction_torque_nm)
                        .sum();
                    (s.crank_angle_deg, sum)
                })
                .collect()
        })
        .collect();
    let (plot, side) = root.split_horizontally(1000 - legend_width(&joints));
    let x1 = t
        .samples
        .last()
        .map_or(360.0, |s| s.crank_angle_deg)
        .max(1.0);
    let (y0, y1) = range(series.iter().flatten().map(|p| p.1).chain([0.0]), 0.05);
    let mut chart = frame(
        &plot,
        &format!("Friction torque over the cycle at {:.0} rpm", t.speed_rpm),
        0.0..x1,
        y0..y1,
        "crank angle (degrees)",
        "friction torque at the crank (N m)",
    )?;
    for (k, pts) in series.into_iter().enumerate() {
        draw_styled(&mut chart, pts, series_style(k), 2)?;
    }
    let entries: Vec<(String, Swatch)> = joints
        .iter()
        .enumerate()
        .map(|(k, j)| (j.clone(), Swatch::Line(series_style(k))))
        .collect();
    legend_beside(&side, "joint", &entries)?;
    root.present()?;
    Ok(())
}

/// The polar load diagram of a plateau's cycle: the big-end force (crank on rod) and the
/// main-bearing force (ground on crank) as vectors in the engine frame, x across and y along
/// the cylinder axis (`run --crank-angle`).
pub fn bearing_polar_svg(t: &crate::sim::CrankAngleTrace) -> std::io::Result<String> {
    svg(|s| bearing_polar_plot(t, s))
}

fn bearing_polar_plot(t: &crate::sim::CrankAngleTrace, out: &mut String) -> PlotResult {
    let root = SVGBackend::with_string(out, (960, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let big: Vec<(f64, f64)> = t
        .samples
        .iter()
        .map(|s| (s.big_end_n[0], s.big_end_n[1]))
        .collect();
    let main: Vec<(f64, f64)> = t
        .samples
        .iter()
        .map(|s| (s.main_n[0], s.main_n[1]))
        .collect();
    let reach = big
        .iter()
        .chain(&main)
        .map(|p| p.0.abs().max(p.1.abs()))
        .fold(1.0_f64, f64::max)
        * 1.1;
    let series = [
        ("big end (crank on rod)".to_string(), big),
        ("main bearings (on crank)".to_string(), main),
    ];
    let names: Vec<String> = series.iter().map(|s| s.0.clone()).collect();
    let (plot, side) = root.split_horizontally(960 - legend_width(&names));
    let mut chart = frame(
        &plot,
        &format!("Bearing loads over the cycle at {:.0} rpm", t.speed_rpm),
        -reach..reach,
        -reach..reach,
        "force across the cylinder, x (N)",
        "force along the cylinder axis, y (N)",
    )?;
    let mut entries = Vec::new();
    for (k, (name, pts)) in series.into_iter().enumerate() {
        let style = series_style(k);
        let mut closed = pts.clone();
        closed.extend(pts.first().copied());
        draw_styled(&mut chart, closed, style, 2)?;
        entries.push((name, Swatch::Line(style)));
    }
    legend_beside(&side, "bearing", &entries)?;
    root.present()?;
    Ok(())
}

/// Whether joint `name` is a piston (`piston`, `piston_N`): a slide, whose law's eccentricity is
/// the lateral offset across the bore, not a journal's locus.
fn is_piston(name: &str) -> bool {
    name == "piston" || name.starts_with("piston_")
}

/// The journals' eccentricity loci of a plateau's cycle: per journal (main bearing, big end,
/// small end) whose law reports its eccentricity (contract v3), the ratio e/c over the cycle
/// inside the unit circle (the bearing wall), in the outer member's frame; `None` where no
/// journal's law reports one (`run --crank-angle`, `eccentricity_RPM.svg`). The pistons'
/// offsets are [`piston_offset_svg`]'s.
pub fn eccentricity_polar_svg(t: &crate::sim::CrankAngleTrace) -> Option<std::io::Result<String>> {
    let loci: Vec<Locus> = eccentricity_samples(t, false)
        .into_iter()
        .map(|(label, pts)| (label, pts.iter().map(|&(_, x, y)| (x, y)).collect()))
        .collect();
    if loci.is_empty() {
        return None;
    }
    Some(svg(|s| eccentricity_polar_plot(t.speed_rpm, &loci, s)))
}

/// The pistons' lateral offsets over a plateau's cycle: per piston whose law reports its
/// eccentricity (the piston skirt: `(0, e/c)` in the cylinder frame), the offset across the
/// bore as a fraction of the skirt's clearance against crank angle; `None` where no piston's
/// law reports one (`run --crank-angle`, `piston_offset_RPM.svg`).
pub fn piston_offset_svg(t: &crate::sim::CrankAngleTrace) -> Option<std::io::Result<String>> {
    let offsets: Vec<Locus> = eccentricity_samples(t, true)
        .into_iter()
        .map(|(label, pts)| (label, pts.iter().map(|&(a, _, y)| (a, y)).collect()))
        .collect();
    if offsets.is_empty() {
        return None;
    }
    Some(svg(|s| piston_offset_plot(t, &offsets, s)))
}

/// A joint's legend label (joint and law) and its points.
type Locus = (String, Vec<(f64, f64)>);

/// A joint's legend label and its eccentricity ratio by crank angle: (degrees, x, y).
type Sampled = (String, Vec<(f64, f64, f64)>);

/// Per joint (the pistons if `pistons`, else the journals), the first of its laws that reports
/// an eccentricity, labelled "joint (law)", and the ratio where it reports it: (crank angle in
/// degrees, x, y).
fn eccentricity_samples(t: &crate::sim::CrankAngleTrace, pistons: bool) -> Vec<Sampled> {
    let mut loci: Vec<Sampled> = Vec::new();
    let mut seen: Vec<&str> = Vec::new();
    for (k, (joint, law)) in t.laws.iter().enumerate() {
        if seen.contains(&joint.as_str()) || is_piston(joint) != pistons {
            continue;
        }
        let pts: Vec<(f64, f64, f64)> = t
            .samples
            .iter()
            .filter_map(|s| {
                let l = s.laws.get(k)?;
                Some((s.crank_angle_deg, l.eccentricity_x?, l.eccentricity_y?))
            })
            .collect();
        if !pts.is_empty() {
            seen.push(joint);
            loci.push((format!("{joint} ({law})"), pts));
        }
    }
    loci
}

fn eccentricity_polar_plot(speed_rpm: f64, loci: &[Locus], out: &mut String) -> PlotResult {
    let root = SVGBackend::with_string(out, (900, 760)).into_drawing_area();
    root.fill(&WHITE)?;
    let names: Vec<String> = loci.iter().map(|(j, _)| j.clone()).collect();
    let (plot, side) = root.split_horizontally(900 - legend_width(&names).max(200));
    let (plot, note) = plot.split_vertically(695);
    let mut chart = frame(
        &plot,
        &format!("Journal eccentricity e/c over the cycle at {speed_rpm:.0} rpm"),
        -1.1..1.1,
        -1.1..1.1,
        "e/c, x (-): across the bore (mains) or the rod (big ends)",
        "e/c, y (-): towards the head (mains) or the small end (big ends)",
    )?;
    // The bearing wall: |e| = c.
    let wall: Vec<(f64, f64)> = (0..=360)
        .map(|d| {
            let a = f64::from(d).to_radians();
            (a.cos(), a.sin())
        })
        .collect();
    chart.draw_series(LineSeries::new(wall, BLACK.stroke_width(1)))?;
    for (k, (_, pts)) in loci.iter().enumerate() {
        let style = series_style(k);
        let mut closed = pts.clone();
        closed.extend(pts.first().copied());
        draw_styled(&mut chart, closed, style, 2)?;
        // The cycle's start (crank angle 0) marked, so the direction of travel reads.
        draw_markers(&mut chart, k, &pts[..1.min(pts.len())], style.color)?;
    }
    note_lines(
        &note,
        &[
            "Journal centre offset e over the radial clearance c, in the outer member's frame: the",
            "block for mains, the rod for big ends; angles counter-clockwise from +x seen from the",
            "drive end. Marker: crank angle 0. Circle: the bearing wall (e = c).",
        ],
    )?;
    let entries: Vec<(String, Swatch)> = names
        .iter()
        .enumerate()
        .map(|(k, j)| (j.clone(), Swatch::Marked(series_style(k), k)))
        .collect();
    legend_beside(&side, "journal (law)", &entries)?;
    root.present()?;
    Ok(())
}

fn piston_offset_plot(
    t: &crate::sim::CrankAngleTrace,
    offsets: &[Locus],
    out: &mut String,
) -> PlotResult {
    let root = SVGBackend::with_string(out, (1000, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    let names: Vec<String> = offsets.iter().map(|(j, _)| j.clone()).collect();
    let (plot, side) = root.split_horizontally(1000 - legend_width(&names).max(200));
    let (plot, note) = plot.split_vertically(545);
    let x1 = t
        .samples
        .last()
        .map_or(360.0, |s| s.crank_angle_deg)
        .max(1.0);
    let mut chart = frame(
        &plot,
        &format!(
            "Piston lateral offset in the bore over the cycle at {:.0} rpm",
            t.speed_rpm
        ),
        0.0..x1,
        -1.1..1.1,
        "crank angle (degrees)",
        "lateral offset e/c (-), across the bore",
    )?;
    // The skirt's pads on the liner: e = +c and e = -c.
    for wall in [-1.0, 1.0] {
        chart.draw_series(LineSeries::new(
            [(0.0, wall), (x1, wall)],
            BLACK.stroke_width(1),
        ))?;
    }
    for (k, (_, pts)) in offsets.iter().enumerate() {
        draw_styled(&mut chart, pts.clone(), series_style(k), 2)?;
    }
    note_lines(
        &note,
        &[
            "The piston's offset e across the bore over the skirt's radial clearance c, positive",
            "towards the cylinder frame's +y (normal to the bore's axis). Lines: the pads on the liner (e = c).",
        ],
    )?;
    let entries: Vec<(String, Swatch)> = names
        .iter()
        .enumerate()
        .map(|(k, j)| (j.clone(), Swatch::Line(series_style(k))))
        .collect();
    legend_beside(&side, "piston (law)", &entries)?;
    root.present()?;
    Ok(())
}

/// FMEP against crank speed per component, Tribo's and the correlation's: one colour per
/// component, Tribo solid and the correlation dashed (`run --fmep`'s `fmep_correlation.svg`,
/// `compare`'s `correlation_<set>.svg`); FMEP from 0.
pub(crate) fn correlation_svg(title: &str, series: &[Series]) -> std::io::Result<String> {
    svg(|out| {
        let root = SVGBackend::with_string(out, (1100, 600)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut entries: Vec<(String, Swatch)> = Vec::new();
        for (k, (label, ..)) in series.iter().enumerate() {
            let color = PALETTE[k % PALETTE.len()];
            for (who, dash) in [("Tribo", DASHES[0]), ("correlation", DASHES[1])] {
                entries.push((
                    format!("{label}: {who}"),
                    Swatch::Line(SeriesStyle { color, dash }),
                ));
            }
        }
        let labels: Vec<String> = entries.iter().map(|e| e.0.clone()).collect();
        let (plot, side) = root.split_horizontally(1100 - legend_width(&labels));
        let (x0, x1) = range(series.iter().flat_map(|x| x.1.iter().copied()), 0.05);
        let ys = series
            .iter()
            .flat_map(|x| x.2.iter().chain(x.3.iter()).filter_map(|v| *v));
        let (_, y1) = range(ys.chain([0.0]), 0.1);
        let mut chart = frame(
            &plot,
            title,
            x0..x1,
            0.0..y1,
            "crank speed (rpm)",
            "FMEP (kPa)",
        )?;
        let mut k = 0;
        for (_, x, tribo, corr) in series {
            for values in [tribo, corr] {
                let pts: Vec<(f64, f64)> = x
                    .iter()
                    .zip(values)
                    .filter_map(|(a, b)| b.map(|y| (*a, y)))
                    .collect();
                if let Swatch::Line(style) = entries[k].1 {
                    draw_styled(&mut chart, pts, style, 2)?;
                }
                k += 1;
            }
        }
        legend_beside(&side, "component: source", &entries)?;
        root.present()?;
        Ok(())
    })
}

/// Lines of explanation under a plot, in `area`.
fn note_lines(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    lines: &[&str],
) -> PlotResult {
    area.fill(&WHITE)?;
    for (i, line) in lines.iter().enumerate() {
        area.draw(&Text::new(
            *line,
            (20, 4 + 17 * i as i32),
            ("sans-serif", 13),
        ))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_ranges_are_finite_whatever_the_values() {
        let cases: [&[f64]; 6] = [
            &[1e308, -1e308],
            &[f64::MAX, f64::MIN, f64::NAN],
            &[f64::INFINITY, f64::NEG_INFINITY],
            &[],
            &[3.0, 3.0],
            &[1e300, 1e300],
        ];
        for values in cases {
            let (lo, hi) = range(values.iter().copied(), 0.15);
            assert!(
                lo.is_finite() && hi.is_finite() && lo < hi,
                "{values:?}: {lo}..{hi}"
            );
            assert!(hi - lo <= 2.0 * AXIS_LIMIT * 1.31, "{values:?}: {lo}..{hi}");
        }
        // Ordinary values keep their padded range.
        let (lo, hi) = range([1.0, 3.0].into_iter(), 0.5);
        assert_eq!((lo, hi), (0.0, 4.0));
    }

    #[test]
    fn a_chart_of_absurd_values_is_drawn_quickly() {
        let start = std::time::Instant::now();
        let (x0, x1) = range([1e308, -1e308, 3000.0].into_iter(), 0.05);
        let (y0, y1) = range([1e308, -1e308, f64::NAN].into_iter(), 0.15);
        let text = svg(|s| {
            let root = SVGBackend::with_string(s, (900, 560)).into_drawing_area();
            let mut chart = frame(&root, "absurd", x0..x1, y0..y1, "x", "y")?;
            chart.draw_series(LineSeries::new([(1e308, -1e308), (x0, y1)], BLACK))?;
            root.present()?;
            Ok(())
        })
        .expect("drawn");
        assert!(text.contains("<svg"));
        assert!(start.elapsed().as_secs_f64() < 5.0, "{:?}", start.elapsed());
    }
}

#[cfg(test)]
mod eccentricity_tests {
    use super::*;
    use crate::sim::{AngleSample, CrankAngleTrace, LawSample};

    /// A law's sample reporting the eccentricity ratio (x, y).
    fn sample(x: f64, y: f64) -> LawSample {
        LawSample {
            friction_torque_nm: 0.1,
            power_w: 10.0,
            normal_load_n: 100.0,
            sliding_speed_m_s: 1.0,
            regime: "hydrodynamic".into(),
            min_film_m: Some(1e-6),
            eccentricity_x: Some(x),
            eccentricity_y: Some(y),
            peak_pressure_pa: None,
            asperity_share: None,
        }
    }

    /// A main bearing on a circle of e/c 0.5 and a skirt offset 0.3 sin(theta) across the bore.
    fn trace() -> CrankAngleTrace {
        let samples = (0..36)
            .map(|k| {
                let a = f64::from(k) * 10.0;
                let r = a.to_radians();
                AngleSample {
                    crank_angle_deg: a,
                    laws: vec![
                        sample(0.5 * r.cos(), 0.5 * r.sin()),
                        sample(0.0, 0.3 * r.sin()),
                    ],
                    big_end_n: [0.0; 2],
                    main_n: [0.0; 2],
                    pressures_pa: [1e5; 2],
                    drive_torque_nm: 0.0,
                    cylinders: Vec::new(),
                    mains_n: Vec::new(),
                }
            })
            .collect();
        CrankAngleTrace {
            speed_rpm: 3000.0,
            laws: vec![
                ("main_1".into(), "plain-journal".into()),
                ("piston_1".into(), "piston-skirt".into()),
            ],
            samples,
            warnings: Vec::new(),
        }
    }

    /// The text elements of an SVG.
    fn texts(svg: &str) -> Vec<String> {
        svg.split("<text")
            .skip(1)
            .filter_map(|t| {
                Some(
                    t.split_once('>')?
                        .1
                        .split_once("</text>")?
                        .0
                        .trim()
                        .to_string(),
                )
            })
            .collect()
    }

    /// The journals' loci and the pistons' offsets are drawn apart, each on axes that say what
    /// they are, with units, and a legend naming joint and law: the skirt's lateral offset is
    /// not drawn as a journal's eccentricity.
    #[test]
    fn a_skirt_s_offset_is_not_drawn_as_a_journal_s_eccentricity() {
        let t = trace();
        let polar = eccentricity_polar_svg(&t)
            .expect("a journal")
            .expect("renders");
        let polar = texts(&polar);
        assert!(
            polar.iter().any(|s| s == "main_1 (plain-journal)"),
            "{polar:?}"
        );
        assert!(polar.iter().all(|s| !s.contains("piston")), "{polar:?}");
        assert!(
            polar.iter().any(|s| s.starts_with("e/c, x (-)")),
            "{polar:?}"
        );
        let offset = piston_offset_svg(&t).expect("a piston").expect("renders");
        let offset = texts(&offset);
        for label in [
            "Piston lateral offset in the bore over the cycle at 3000 rpm",
            "crank angle (degrees)",
            "lateral offset e/c (-), across the bore",
            "piston_1 (piston-skirt)",
        ] {
            assert!(offset.iter().any(|s| s == label), "{label}: {offset:?}");
        }
        assert!(offset.iter().all(|s| !s.contains("main_1")), "{offset:?}");
        // The offset is drawn against crank angle: its points are (angle, e/c across).
        let pistons = eccentricity_samples(&t, true);
        let (_, pts) = &pistons[0];
        assert_eq!(pts.len(), 36);
        let (a, _, y) = pts[9];
        assert!(
            (a - 90.0).abs() < 1e-12 && (y - 0.3).abs() < 1e-12,
            "{a} {y}"
        );
        // A trace without pistons' eccentricity has no offset plot.
        let mut journal_only = t.clone();
        journal_only.laws.truncate(1);
        journal_only
            .samples
            .iter_mut()
            .for_each(|s| s.laws.truncate(1));
        assert!(piston_offset_svg(&journal_only).is_none());
    }
}
