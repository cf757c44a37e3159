//! Draws docs/laws/ring-pack-crank-angle.svg from a `tribo run --crank-angle` result: the ring
//! pack's friction force on the piston and its asperity share against crank angle.
//!
//! ```sh
//! tribo run crf250r-motored --steady --law piston=ring-pack --crank-angle out
//! cargo run --release -p tribo-law-ring-pack --example crank_angle_plot -- \
//!     out/crank_angle.csv docs/laws/ring-pack-crank-angle.svg 3000,6000,9000
//! ```

use plotters::prelude::*;
use std::error::Error;

/// (speed rpm, crank angle deg, friction force on the piston N, asperity share)
type Row = (f64, f64, f64, f64);

fn read(path: &str) -> Result<Vec<Row>, Box<dyn Error>> {
    let text = std::fs::read_to_string(path)?;
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().ok_or("empty file")?.split(',').collect();
    let col = |name: &str| {
        head.iter()
            .position(|h| *h == name)
            .ok_or_else(|| format!("{path}: no column `{name}`"))
    };
    let (rpm, deg, law, power, speed, share) = (
        col("speed_rpm")?,
        col("crank_angle_deg")?,
        col("law")?,
        col("power_w")?,
        col("sliding_speed_m_s")?,
        col("asperity_share")?,
    );
    let mut out = vec![];
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        if f.get(law) != Some(&"ring-pack") {
            continue;
        }
        let num = |i: usize| -> Result<f64, Box<dyn Error>> {
            Ok(f.get(i).ok_or("short line")?.parse::<f64>()?)
        };
        let v = num(speed)?;
        // The dissipated power is |F v|; the force opposes the sliding.
        let force = if v == 0.0 { 0.0 } else { -num(power)? / v };
        out.push((num(rpm)?, num(deg)?, force, num(share).unwrap_or(0.0)));
    }
    Ok(out)
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        return Err("usage: crank_angle_plot CRANK_ANGLE.csv OUT.svg RPM[,RPM...]".into());
    }
    let rows = read(&args[1])?;
    let speeds: Vec<f64> = args[3]
        .split(',')
        .map(|s| s.parse::<f64>())
        .collect::<Result<_, _>>()?;
    let root = SVGBackend::new(&args[2], (900, 640)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(400);
    let f_max = rows
        .iter()
        .filter(|r| speeds.contains(&r.0))
        .map(|r| r.2.abs())
        .fold(0.0, f64::max)
        * 1.1;
    let colours = [BLUE, RGBColor(0, 140, 0), RED];
    let mut chart = ChartBuilder::on(&top)
        .caption(
            "ring-pack on crf250r-motored: friction force on the piston",
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..360.0, -f_max..f_max)?;
    chart
        .configure_mesh()
        .x_desc("crank angle from TDC, deg")
        .y_desc("force, N")
        .x_labels(13)
        .draw()?;
    for (k, rpm) in speeds.iter().enumerate() {
        let c = colours[k % colours.len()];
        chart
            .draw_series(LineSeries::new(
                rows.iter().filter(|r| r.0 == *rpm).map(|r| (r.1, r.2)),
                c.stroke_width(2),
            ))?
            .label(format!("{rpm} rpm"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    let s_max = rows
        .iter()
        .filter(|r| speeds.contains(&r.0))
        .map(|r| r.3)
        .fold(0.0, f64::max)
        .max(1e-3)
        * 1.1;
    let mut chart = ChartBuilder::on(&bottom)
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..360.0, 0.0..s_max)?;
    chart
        .configure_mesh()
        .x_desc("crank angle from TDC, deg")
        .y_desc("asperity share of the ring load")
        .x_labels(13)
        .draw()?;
    for (k, rpm) in speeds.iter().enumerate() {
        let c = colours[k % colours.len()];
        chart.draw_series(LineSeries::new(
            rows.iter().filter(|r| r.0 == *rpm).map(|r| (r.1, r.3)),
            c.stroke_width(2),
        ))?;
    }
    root.present()?;
    Ok(())
}
