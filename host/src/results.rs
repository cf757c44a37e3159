//! Result directories: what `run --csv`, `--fmep` and `--crank-angle`, `compare --out`,
//! `mass-response --out` and `sweep --out` write, each set rendered into a temporary directory
//! and swapped in whole ([`ResultDir`]). This module puts together the tables of
//! [`crate::report`], the plots of [`crate::plots`] and the correlation files of
//! [`crate::beside`]; none of those writes a result directory that holds another's files, so
//! they import nothing from each other upwards.

use std::path::Path;

use crate::output::{OutputError, ResultDir};
use crate::plots::{self, io};
use crate::report::{csv_text, fmep_csv, render};
use crate::sim::RunResult;
use crate::study::Comparison;

pub use crate::report::write_csv;

/// `fmep.csv` and the stacked FMEP bars `fmep.svg` in `dir` (`run --fmep`), swapped in whole.
pub fn write_fmep(r: &RunResult, dir: &Path) -> Result<(), OutputError> {
    let mut out = ResultDir::create(dir, "run", "--fmep")?;
    let f = fmep_csv(r).map_err(|source| render("fmep.csv", source))?;
    out.write("fmep.csv", f.as_bytes())?;
    let svg = crate::plots::fmep_svg(r).map_err(|source| render("fmep.svg", source))?;
    out.write("fmep.svg", svg.as_bytes())?;
    crate::beside::write_run(r, &mut out)?;
    out.commit()
}

/// A `crank_angle.csv` column of a law diagnostic: its name and where a sample keeps it.
type DiagnosticColumn = (&'static str, fn(&crate::sim::LawSample) -> Option<f64>);

/// The diagnostics a law may report (contract version 3), as `crank_angle.csv` columns: each
/// column is written when some law of the traces reports it.
const DIAGNOSTIC_COLUMNS: [DiagnosticColumn; 5] = [
    ("min_film_m", |l| l.min_film_m),
    ("eccentricity_x", |l| l.eccentricity_x),
    ("eccentricity_y", |l| l.eccentricity_y),
    ("peak_pressure_pa", |l| l.peak_pressure_pa),
    ("asperity_share", |l| l.asperity_share),
];

/// The crank-angle results of `run --crank-angle DIR`: `crank_angle.csv` (one row per
/// plateau, angle and law: friction torque, power, normal load, sliding speed, regime, and a
/// column for every diagnostic some law reports, empty where a law does not),
/// `crank_angle_loads.csv` (one row per plateau and angle: big-end and main-bearing load
/// vectors, cylinder and crankcase pressure, drive torque), and per plateau the friction
/// torque of every joint over the cycle (`friction_vs_angle_RPM.svg`) and the polar diagram of
/// the big-end and main-bearing loads (`bearing_loads_RPM.svg`), and where a law reports a
/// journal's eccentricity the loci of e/c (`eccentricity_RPM.svg`), where a law reports a
/// piston's the lateral offset e/c against crank angle (`piston_offset_RPM.svg`). Swapped in
/// whole.
pub fn write_crank_angle(
    traces: &[crate::sim::CrankAngleTrace],
    dir: &Path,
) -> Result<(), OutputError> {
    let mut out = ResultDir::create(dir, "run", "--crank-angle")?;
    let diagnostics: Vec<_> = DIAGNOSTIC_COLUMNS
        .iter()
        .filter(|(_, get)| {
            traces
                .iter()
                .flat_map(|t| &t.samples)
                .flat_map(|s| &s.laws)
                .any(|l| get(l).is_some())
        })
        .collect();
    let mut rows = Vec::new();
    let mut loads = Vec::new();
    for t in traces {
        for s in &t.samples {
            for ((joint, law), l) in t.laws.iter().zip(&s.laws) {
                let mut row = vec![
                    t.speed_rpm.to_string(),
                    s.crank_angle_deg.to_string(),
                    joint.clone(),
                    law.clone(),
                    l.friction_torque_nm.to_string(),
                    l.power_w.to_string(),
                    l.normal_load_n.to_string(),
                    l.sliding_speed_m_s.to_string(),
                    l.regime.clone(),
                ];
                row.extend(
                    diagnostics
                        .iter()
                        .map(|(_, get)| get(l).map_or(String::new(), |x| x.to_string())),
                );
                rows.push(row);
            }
            loads.push(vec![
                t.speed_rpm.to_string(),
                s.crank_angle_deg.to_string(),
                s.big_end_n[0].to_string(),
                s.big_end_n[1].to_string(),
                s.main_n[0].to_string(),
                s.main_n[1].to_string(),
                s.pressures_pa[0].to_string(),
                s.pressures_pa[1].to_string(),
                s.drive_torque_nm.to_string(),
            ]);
        }
    }
    let mut header = vec![
        "speed_rpm",
        "crank_angle_deg",
        "joint",
        "law",
        "friction_torque_nm",
        "power_w",
        "normal_load_n",
        "sliding_speed_m_s",
        "regime",
    ];
    header.extend(diagnostics.iter().map(|(name, _)| *name));
    let text = csv_text(&header, rows).map_err(|e| render("crank_angle.csv", e))?;
    out.write("crank_angle.csv", text.as_bytes())?;
    let header = [
        "speed_rpm",
        "crank_angle_deg",
        "big_end_x_n",
        "big_end_y_n",
        "main_x_n",
        "main_y_n",
        "cylinder_pa",
        "crankcase_pa",
        "drive_torque_nm",
    ];
    let text = csv_text(&header, loads).map_err(|e| render("crank_angle_loads.csv", e))?;
    out.write("crank_angle_loads.csv", text.as_bytes())?;
    // An engine's loads per cylinder and per main bearing (the file above has cylinder 1's
    // big end and pressures and the mains' total).
    if traces
        .iter()
        .any(|t| t.samples.iter().any(|s| !s.cylinders.is_empty()))
    {
        let (mut cylinders, mut mains) = (Vec::new(), Vec::new());
        for t in traces {
            for s in &t.samples {
                for (k, c) in s.cylinders.iter().enumerate() {
                    cylinders.push(vec![
                        t.speed_rpm.to_string(),
                        s.crank_angle_deg.to_string(),
                        (k + 1).to_string(),
                        c.big_end_n[0].to_string(),
                        c.big_end_n[1].to_string(),
                        c.side_thrust_n.to_string(),
                        c.pressures_pa[0].to_string(),
                        c.pressures_pa[1].to_string(),
                    ]);
                }
                for (i, m) in s.mains_n.iter().enumerate() {
                    mains.push(vec![
                        t.speed_rpm.to_string(),
                        s.crank_angle_deg.to_string(),
                        format!("main_{}", i + 1),
                        m[0].to_string(),
                        m[1].to_string(),
                    ]);
                }
            }
        }
        let header = [
            "speed_rpm",
            "crank_angle_deg",
            "cylinder",
            "big_end_x_n",
            "big_end_y_n",
            "side_thrust_n",
            "cylinder_pa",
            "crankcase_pa",
        ];
        let text =
            csv_text(&header, cylinders).map_err(|e| render("crank_angle_cylinders.csv", e))?;
        out.write("crank_angle_cylinders.csv", text.as_bytes())?;
        let header = ["speed_rpm", "crank_angle_deg", "main", "x_n", "y_n"];
        let text = csv_text(&header, mains).map_err(|e| render("crank_angle_mains.csv", e))?;
        out.write("crank_angle_mains.csv", text.as_bytes())?;
    }
    for t in traces {
        let name = format!("friction_vs_angle_{:.0}.svg", t.speed_rpm);
        let svg = crate::plots::friction_vs_angle_svg(t).map_err(|e| render(&name, e))?;
        out.write(&name, svg.as_bytes())?;
        let name = format!("bearing_loads_{:.0}.svg", t.speed_rpm);
        let svg = crate::plots::bearing_polar_svg(t).map_err(|e| render(&name, e))?;
        out.write(&name, svg.as_bytes())?;
        if let Some(svg) = crate::plots::eccentricity_polar_svg(t) {
            let name = format!("eccentricity_{:.0}.svg", t.speed_rpm);
            let svg = svg.map_err(|e| render(&name, e))?;
            out.write(&name, svg.as_bytes())?;
        }
        if let Some(svg) = crate::plots::piston_offset_svg(t) {
            let name = format!("piston_offset_{:.0}.svg", t.speed_rpm);
            let svg = svg.map_err(|e| render(&name, e))?;
            out.write(&name, svg.as_bytes())?;
        }
    }
    out.commit()
}

/// Write the result set of a comparison into `dir` (`compare --out`): `comparison.csv`,
/// `scores.csv`, `validation.csv`, the SVG plots, `comparison.json`, and each fitted set with
/// its fitted values as `fitted_<set>.toml` (the values it was ranked by). The set is rendered
/// into a temporary directory and swapped in whole ([`ResultDir`]), so `dir` is always the old
/// set or the new one, and plots of law sets no longer compared disappear with the old set.
pub fn write_comparison(c: &Comparison, dir: &Path) -> Result<(), OutputError> {
    let mut out = ResultDir::create(dir, "compare", "--out")?;
    out.write(
        "comparison.csv",
        rendered("comparison.csv", crate::report::comparison_csv(c))?.as_bytes(),
    )?;
    out.write(
        "scores.csv",
        rendered("scores.csv", crate::report::scores_csv(c))?.as_bytes(),
    )?;
    out.write(
        "validation.csv",
        rendered("validation.csv", crate::report::validation_csv(c))?.as_bytes(),
    )?;
    let name = "torque_vs_speed.svg";
    out.write(name, rendered(name, plots::torque_svg(c))?.as_bytes())?;
    for set in &c.sets {
        let name = format!("contributions_{}.svg", set.lawset);
        let text = rendered(&name, plots::contributions_svg(set))?;
        out.write(&name, text.as_bytes())?;
    }
    let name = "piston_regimes.svg";
    out.write(name, rendered(name, plots::regimes_svg(c))?.as_bytes())?;
    let json = rendered(
        "comparison.json",
        serde_json::to_string_pretty(c).map_err(io),
    )?;
    out.write("comparison.json", json.as_bytes())?;
    for set in &c.sets {
        if let (Some(name), Some(text)) = (fitted_file(set), &set.fitted_lawset_toml) {
            out.write(&name, text.as_bytes())?;
        }
    }
    crate::beside::write_comparison(c, &mut out)?;
    out.commit()
}

/// The file a fitted set's calibrated law set is written to, `fitted_<set>.toml`.
pub fn fitted_file(s: &crate::study::SetResult) -> Option<String> {
    s.fitted_lawset_toml
        .as_ref()
        .map(|_| format!("fitted_{}.toml", plots::file_stem(&s.lawset)))
}

/// Write the result set of a mass study into `dir` (`mass-response --out`):
/// `mass_response.json`, and with `sweep_plot` (a sweep of scales) `mass_sweep.svg`, the torque
/// change against scale factor. Swapped in whole like [`write_comparison`]. Returns the names
/// of the files written.
pub fn write_mass_response(
    r: &[crate::study::MassResponse],
    dir: &Path,
    sweep_plot: bool,
) -> Result<Vec<String>, OutputError> {
    let mut out = ResultDir::create(dir, "mass-response", "--out")?;
    let json = rendered(
        "mass_response.json",
        serde_json::to_string_pretty(r).map_err(io),
    )?;
    out.write("mass_response.json", json.as_bytes())?;
    for (name, text) in [
        ("mass_response.csv", crate::report::mass_csv(r)),
        (
            "mass_response_joints.csv",
            crate::report::mass_joints_csv(r),
        ),
    ] {
        out.write(name, rendered(name, text)?.as_bytes())?;
    }
    if sweep_plot {
        let name = "mass_sweep.svg";
        out.write(name, rendered(name, plots::mass_sweep_svg(r))?.as_bytes())?;
    }
    let files = out.files().to_vec();
    out.commit()?;
    Ok(files)
}

/// Write the result set of a sweep into `dir` (`sweep --out`): `sweep.csv`,
/// `sweep_<lawset>.svg` per law set and `sweep.json`, swapped in whole like
/// [`write_comparison`]. Returns the names of the files written.
pub fn write_sweep(s: &crate::study::Sweep, dir: &Path) -> Result<Vec<String>, OutputError> {
    let mut out = ResultDir::create(dir, "sweep", "--out")?;
    let csv = rendered("sweep.csv", crate::report::sweep_csv(s).map_err(io))?;
    out.write("sweep.csv", csv.as_bytes())?;
    for set in &s.sets {
        let name = format!("sweep_{}.svg", plots::file_stem(&set.lawset));
        let text = rendered(&name, plots::sweep_svg(s, set))?;
        out.write(&name, text.as_bytes())?;
    }
    let json = rendered("sweep.json", serde_json::to_string_pretty(s).map_err(io))?;
    out.write("sweep.json", json.as_bytes())?;
    crate::beside::write_sweep(s, &mut out)?;
    let files = out.files().to_vec();
    out.commit()?;
    Ok(files)
}

/// A rendered file's text, or the error naming the file.
fn rendered<T>(what: &str, r: std::io::Result<T>) -> Result<T, OutputError> {
    r.map_err(|error| render(what, error))
}
