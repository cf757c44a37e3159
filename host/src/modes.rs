//! `tribo modes`: the drivetrain's natural frequencies and mode shapes as a table, and the
//! Campbell diagram (engine orders against crank speed, the modes, the rig's plateaus) as SVG.

use std::fmt::Write as _;
use std::path::Path;

use plotters::prelude::*;

use crate::drivetrain::{campbell_orders, ModalReport};
use crate::output::OutputError;

/// The report as text: the chain at crank speed, then each mode with the spring that carries
/// most of its strain energy and the orders that cross it inside the plateaus.
pub fn text(r: &ModalReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Drivetrain of {} at crank speed (motor {}):",
        r.rig, r.motor_hold
    );
    for n in &r.inertias {
        let _ = writeln!(
            s,
            "  inertia  {:<24} {:>12.4e} kg m^2",
            n.name, n.inertia_kg_m2
        );
    }
    for k in &r.springs {
        let _ = writeln!(
            s,
            "  spring   {:<24} {:>12.1} N m/rad   ({} - {})",
            k.name, k.stiffness_nm_per_rad, k.between[0], k.between[1]
        );
    }
    let _ = writeln!(
        s,
        "Modes (undamped, crank train at its cycle-mean inertia):"
    );
    for (i, m) in r.modes.iter().enumerate() {
        let orders: Vec<String> = m
            .crossings
            .iter()
            .map(|c| format!("{} at {:.0} rpm", fmt_order(c.order), c.speed_rpm))
            .collect();
        let crossing = if orders.is_empty() {
            "no order 0.5-12 crosses it at the plateau speeds".to_string()
        } else {
            format!("crossed by order {}", orders.join(", "))
        };
        let _ = writeln!(
            s,
            "  {:>2}  {:>9.1} Hz  mostly in `{}`; {}",
            i + 1,
            m.frequency_hz,
            m.dominant_spring,
            crossing
        );
    }
    s
}

/// The transducer's figures per plateau of a run with a drivetrain (empty without one): the
/// mean shaft torque and the acquired record's mean, the extremes and peak-to-peak against the
/// rating, the crank's speed fluctuation.
pub fn instrument_text(r: &crate::sim::RunResult) -> String {
    let rows: Vec<(f64, &crate::sim::Instrument)> = r
        .plateaus
        .iter()
        .filter_map(|p| p.instrument.as_ref().map(|i| (p.set_speed_rpm, i)))
        .collect();
    let Some((_, first)) = rows.first() else {
        return String::new();
    };
    let mut s = format!(
        "Transducer `{}` (rated {:.1} N m, limit {:.1} N m, oscillation width {:.1} N m p-p):\n",
        first.transducer, first.rated_torque_nm, first.limit_torque_nm, first.oscillation_width_nm
    );
    let _ = writeln!(
        s,
        "  {:>6}  {:>10}  {:>10}  {:>9}  {:>9}  {:>9}  {:>10}  rating",
        "rpm", "mean N m", "acq. N m", "min N m", "max N m", "p-p N m", "speed fl."
    );
    for (rpm, i) in rows {
        let _ = writeln!(
            s,
            "  {:>6.0}  {:>10.4}  {:>10.4}  {:>9.3}  {:>9.3}  {:>9.3}  {:>9.2}%  {}",
            rpm,
            i.mean_torque_nm + 0.0,
            i.acquired_mean_torque_nm + 0.0,
            i.min_torque_nm + 0.0,
            i.max_torque_nm + 0.0,
            i.peak_to_peak_nm,
            100.0 * i.crank_speed_fluctuation,
            if i.within_rating() {
                "within"
            } else {
                "OUTSIDE"
            }
        );
    }
    s
}

/// An order as written in reports: `2`, `1.5`.
fn fmt_order(order: f64) -> String {
    if order.fract() == 0.0 {
        format!("{order:.0}")
    } else {
        format!("{order:.1}")
    }
}

/// The Campbell diagram as SVG: orders 0.5-12 as lines through the origin (whole orders solid,
/// half orders dashed grey), each mode's frequency as a horizontal line, each plateau as a
/// vertical line, and a dot where an order crosses a mode at a plateau speed range.
pub fn campbell_svg(r: &ModalReport) -> std::io::Result<String> {
    let mut out = String::new();
    draw(r, &mut out).map_err(|e| std::io::Error::other(e.to_string()))?;
    Ok(out)
}

/// Write [`campbell_svg`] to `path` atomically (a temporary file beside it, renamed).
pub fn write_campbell(r: &ModalReport, path: &Path) -> Result<(), OutputError> {
    let text = campbell_svg(r).map_err(|error| OutputError::Render {
        what: path.display().to_string(),
        error,
    })?;
    crate::output::write_atomic(path, text.as_bytes())
}

type DrawResult = Result<(), Box<dyn std::error::Error>>;

fn draw(r: &ModalReport, out: &mut String) -> DrawResult {
    let top_rpm = r.plateaus_rpm.iter().fold(1000.0_f64, |a, v| a.max(*v)) * 1.1;
    let top_hz = 12.0 * top_rpm / 60.0;
    let root = SVGBackend::with_string(out, (960, 640)).into_drawing_area();
    root.fill(&WHITE)?;
    let (plot, side) = root.split_horizontally(760);
    let mut chart = ChartBuilder::on(&plot)
        .caption(
            format!("Campbell diagram: {} drivetrain", r.rig),
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0..top_rpm, 0.0..top_hz)?;
    chart
        .configure_mesh()
        .x_desc("crank speed (rpm)")
        .y_desc("frequency (Hz)")
        .x_label_formatter(&|v| crate::plots::tick_label(*v, 0))
        .y_label_formatter(&|v| crate::plots::tick_label(*v, 0))
        .draw()?;
    for order in campbell_orders() {
        let whole = order.fract() == 0.0;
        let style = if whole {
            ShapeStyle::from(&RGBColor(90, 90, 90)).stroke_width(1)
        } else {
            ShapeStyle::from(&RGBColor(190, 190, 190)).stroke_width(1)
        };
        chart.draw_series(LineSeries::new(
            [(0.0, 0.0), (top_rpm, order * top_rpm / 60.0)],
            style,
        ))?;
        if whole {
            // Each whole order named where its line leaves the plot (right or top edge).
            let at = if order * top_rpm / 60.0 <= top_hz {
                (top_rpm * 0.985, order * top_rpm / 60.0)
            } else {
                (60.0 * top_hz / order, top_hz * 0.985)
            };
            chart.draw_series(std::iter::once(Text::new(
                format!("{order:.0}"),
                at,
                ("sans-serif", 12).into_font().color(&RGBColor(60, 60, 60)),
            )))?;
        }
    }
    for p in &r.plateaus_rpm {
        chart.draw_series(DashedLineSeries::new(
            [(*p, 0.0), (*p, top_hz)],
            6,
            4,
            ShapeStyle::from(&RGBColor(0, 110, 0)).stroke_width(1),
        ))?;
    }
    for m in r.modes.iter().filter(|m| m.frequency_hz <= top_hz) {
        chart.draw_series(LineSeries::new(
            [(0.0, m.frequency_hz), (top_rpm, m.frequency_hz)],
            ShapeStyle::from(&RGBColor(200, 30, 30)).stroke_width(2),
        ))?;
        chart.draw_series(m.crossings.iter().map(|c| {
            Circle::new(
                (c.speed_rpm, m.frequency_hz),
                4,
                RGBColor(200, 30, 30).filled(),
            )
        }))?;
    }
    legend(r, &side, top_hz)
}

/// The key beside the plot: what the lines are, and the modes above the plotted range.
fn legend(
    r: &ModalReport,
    side: &DrawingArea<SVGBackend, plotters::coord::Shift>,
    top_hz: f64,
) -> DrawResult {
    let font = ("sans-serif", 14).into_font();
    // The key in a box, beside the plot (the plot's style guide: crate::plots).
    let (w, _) = side.dim_in_pixel();
    let rows = 6 + r.modes.len() as i32;
    side.draw(&Rectangle::new(
        [(2, 24), (w as i32 - 4, 40 + 20 * rows)],
        BLACK.stroke_width(1),
    ))?;
    let mut y = 40;
    let mut line = |text: String, color: RGBColor| -> DrawResult {
        side.draw(&Text::new(text, (8, y), font.clone().color(&color)))?;
        y += 20;
        Ok(())
    };
    line("red: modes".into(), RGBColor(200, 30, 30))?;
    line("grey: orders 0.5-12 (whole".into(), RGBColor(90, 90, 90))?;
    line("  orders numbered)".into(), RGBColor(90, 90, 90))?;
    line("green dashed: plateaus".into(), RGBColor(0, 110, 0))?;
    line("dots: crossings".into(), RGBColor(200, 30, 30))?;
    line(String::new(), RGBColor(0, 0, 0))?;
    for (i, m) in r.modes.iter().enumerate() {
        let above = if m.frequency_hz > top_hz {
            " (above)"
        } else {
            ""
        };
        line(
            format!("mode {}: {:.0} Hz{above}", i + 1, m.frequency_hz),
            RGBColor(0, 0, 0),
        )?;
    }
    Ok(())
}
