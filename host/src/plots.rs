//! SVG plots of a comparison (plotters, SVG backend) and the files written with them.

use std::path::Path;

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::output::write_atomic;
use crate::study::Comparison;

type PlotResult = Result<(), Box<dyn std::error::Error>>;

const COLORS: [RGBColor; 10] = [
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

fn io(e: impl std::fmt::Display) -> std::io::Error {
    std::io::Error::other(e.to_string())
}

/// Write `comparison.csv`, `comparison.json` and the SVG plots into `dir`. Every file is
/// written under a temporary name and renamed, so a failed run leaves earlier results intact.
pub fn write_comparison(c: &Comparison, dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let json = serde_json::to_string_pretty(c).map_err(io)?;
    let csv = crate::report::comparison_csv(c)?;
    let scores = crate::report::scores_csv(c)?;
    let validation = crate::report::validation_csv(c)?;
    let mut svgs = vec![(
        "torque_vs_speed.svg".to_string(),
        svg(|s| torque_plot(c, s))?,
    )];
    for set in &c.sets {
        let name = format!("contributions_{}.svg", set.lawset);
        svgs.push((name, svg(|s| contributions_plot(set, s))?));
    }
    svgs.push(("piston_regimes.svg".into(), svg(|s| regimes_plot(c, s))?));
    // Render everything first; only then replace files.
    write_atomic(&dir.join("comparison.csv"), csv.as_bytes())?;
    write_atomic(&dir.join("scores.csv"), scores.as_bytes())?;
    write_atomic(&dir.join("validation.csv"), validation.as_bytes())?;
    for (name, text) in &svgs {
        write_atomic(&dir.join(name), text.as_bytes())?;
    }
    write_atomic(&dir.join("comparison.json"), json.as_bytes())
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
    let mut chart = ChartBuilder::on(root)
        .caption(caption, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(x, y)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .x_label_formatter(&|x| {
            format!("{x:.2}")
                .trim_end_matches('0')
                .trim_end_matches('.')
                .to_string()
        })
        .y_desc(y_desc)
        .draw()?;
    Ok(chart)
}

/// The legend, boxed, at `pos`.
fn legend<'a, 'b: 'a>(chart: &mut Chart<'a, 'b>, pos: SeriesLabelPosition) -> PlotResult {
    chart
        .configure_series_labels()
        .position(pos)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

fn range(values: impl Iterator<Item = f64>, pad: f64) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let span = (hi - lo).max(1e-6);
    (lo - pad * span, hi + pad * span)
}

fn torque_plot(c: &Comparison, out: &mut String) -> PlotResult {
    let root = SVGBackend::with_string(out, (900, 560)).into_drawing_area();
    let speeds: Vec<f64> = c.data.iter().map(|d| d.speed_rpm).collect();
    let (x0, x1) = range(speeds.iter().copied(), 0.05);
    let all = c.data.iter().map(|d| d.torque_nm).chain(
        c.sets
            .iter()
            .flat_map(|s| s.run.plateaus.iter().map(|p| p.motoring_torque_nm)),
    );
    let (y0, y1) = range(all, 0.15);
    let mut chart = frame(
        &root,
        &format!("Motoring torque vs engine speed ({}, {})", c.rig, c.mode),
        x0..x1,
        y0.min(0.0)..y1,
        "engine speed (rpm)",
        "motoring torque (N m)",
    )?;
    // The 95% bands first, shaded, so the measurements and lines stay visible on top of them.
    for (i, s) in c.sets.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        if let (Some(lo), Some(hi)) = (&s.band_lower_nm, &s.band_upper_nm) {
            let mut poly: Vec<(f64, f64)> = Vec::new();
            for (p, h) in s.run.plateaus.iter().zip(hi) {
                poly.push((p.set_speed_rpm, h.min(y1)));
            }
            for (p, l) in s.run.plateaus.iter().zip(lo).rev() {
                poly.push((p.set_speed_rpm, l.max(y0.min(0.0))));
            }
            chart.draw_series(std::iter::once(Polygon::new(
                poly,
                color.mix(0.18).filled(),
            )))?;
        }
    }
    chart
        .draw_series(
            c.data
                .iter()
                .map(|d| Circle::new((d.speed_rpm, d.torque_nm), 5, BLACK.filled())),
        )?
        .label("measured")
        .legend(|(x, y)| Circle::new((x, y), 5, BLACK.filled()));
    for (i, s) in c.sets.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        let pts: Vec<(f64, f64)> = s
            .run
            .plateaus
            .iter()
            .map(|p| (p.set_speed_rpm, p.motoring_torque_nm))
            .collect();
        let loo = s
            .scores
            .cv_rmse_nm
            .map_or("-".to_string(), |v| format!("{v:.3}"));
        let band = if s.band_lower_nm.is_some() && s.scores.free_params > 0 {
            ", shaded: 95% band"
        } else {
            ""
        };
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
            .label(format!(
                "{} (RMSE {:.3}, LOO {loo} N m{band})",
                s.lawset, s.rmse_nm
            ))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart.draw_series(pts.iter().map(|p| Cross::new(*p, 4, color.stroke_width(2))))?;
    }
    legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    root.present()?;
    Ok(())
}

fn contributions_plot(set: &crate::study::SetResult, out: &mut String) -> PlotResult {
    let root = SVGBackend::with_string(out, (900, 560)).into_drawing_area();
    let p = &set.run.plateaus;
    let n_laws = p.first().map_or(0, |x| x.joints.len());
    let speeds: Vec<f64> = p.iter().map(|x| x.set_speed_rpm).collect();
    let (x0, x1) = range(speeds.iter().copied(), 0.02);
    let totals: Vec<f64> = p
        .iter()
        .map(|x| x.joints.iter().map(|j| j.friction_torque_nm.max(0.0)).sum())
        .collect();
    let (_, y1) = range(totals.iter().copied().chain([0.0]), 0.1);
    let mut chart = frame(
        &root,
        &format!("Friction torque by joint and law: {}", set.lawset),
        x0..x1,
        0.0..y1,
        "engine speed (rpm)",
        "friction torque at the crank (N m)",
    )?;
    // Stack: draw the cumulative sums from the top down so each band shows its own share.
    for k in (0..n_laws).rev() {
        let color = COLORS[k % COLORS.len()];
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
        let label = p
            .first()
            .map(|x| format!("{} ({})", x.joints[k].joint, x.joints[k].law))
            .unwrap_or_default();
        chart
            .draw_series(AreaSeries::new(pts, 0.0, color.mix(0.75)).border_style(color))?
            .label(label)
            .legend(move |(x, y)| {
                Rectangle::new([(x, y - 5), (x + 20, y + 5)], color.mix(0.75).filled())
            });
    }
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present()?;
    Ok(())
}

fn regimes_plot(c: &Comparison, out: &mut String) -> PlotResult {
    let root = SVGBackend::with_string(out, (900, 560)).into_drawing_area();
    let speeds: Vec<f64> = c.data.iter().map(|d| d.speed_rpm).collect();
    let (x0, x1) = range(speeds.iter().copied(), 0.02);
    let mut chart = frame(
        &root,
        "Lubrication regime of the piston (time share)",
        x0..x1,
        0.0..1.05,
        "engine speed (rpm)",
        "time share of the regime (-)",
    )?;
    let mut any = false;
    for (i, s) in c.sets.iter().enumerate() {
        let piston: Vec<_> = s
            .run
            .plateaus
            .iter()
            .filter_map(|p| {
                p.joints
                    .iter()
                    .find(|j| j.joint == "piston" && j.regime_share.none < 0.5)
                    .map(|j| (p.set_speed_rpm, j.regime_share))
            })
            .collect();
        if piston.is_empty() {
            continue;
        }
        any = true;
        let names = ["boundary", "mixed", "hydrodynamic"];
        for (r, name) in names.iter().enumerate() {
            let color = COLORS[(3 * i + r) % COLORS.len()];
            let pts: Vec<(f64, f64)> = piston
                .iter()
                .map(|(v, sh)| (*v, [sh.boundary, sh.mixed, sh.hydrodynamic][r]))
                .collect();
            chart
                .draw_series(LineSeries::new(pts, color.stroke_width(2)))?
                .label(format!("{}: {name}", s.lawset))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
    }
    if !any {
        chart.draw_series(std::iter::once(Text::new(
            "no law set reports a piston regime",
            (x0 + 0.05 * (x1 - x0), 0.5),
            ("sans-serif", 18),
        )))?;
    } else {
        legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    }
    root.present()?;
    Ok(())
}

/// Torque change against scale factor, one line per law set and speed.
pub fn write_mass_sweep(r: &[crate::study::MassResponse], path: &Path) -> std::io::Result<()> {
    let text = svg(|out| {
        let root = SVGBackend::with_string(out, (900, 560)).into_drawing_area();
        let all = r.iter().flat_map(|s| s.changes.iter());
        let (x0, x1) = range(all.clone().map(|c| c.scale), 0.03);
        let (y0, y1) = range(all.map(|c| c.change_nm).chain([0.0]), 0.1);
        let body = r
            .first()
            .map(|s| format!("{:?}", s.body).to_lowercase())
            .unwrap_or_default();
        let mut chart = frame(
            &root,
            &format!("Motoring torque change vs {body} mass scale"),
            x0..x1,
            y0..y1,
            &format!("{body} mass scale (-)"),
            "torque change (N m)",
        )?;
        let mut k = 0;
        for set in r {
            let mut speeds: Vec<f64> = set.changes.iter().map(|c| c.speed_rpm).collect();
            speeds.sort_by(f64::total_cmp);
            speeds.dedup();
            for sp in speeds {
                let color = COLORS[k % COLORS.len()];
                k += 1;
                let mut pts: Vec<(f64, f64)> = set
                    .changes
                    .iter()
                    .filter(|c| c.speed_rpm == sp)
                    .map(|c| (c.scale, c.change_nm))
                    .collect();
                pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                chart
                    .draw_series(LineSeries::new(pts, color.stroke_width(2)))?
                    .label(format!("{} {:.0} rpm", set.lawset, sp))
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                    });
            }
        }
        legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
        root.present()?;
        Ok(())
    })?;
    write_atomic(path, text.as_bytes())
}
