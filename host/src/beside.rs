//! The Sandoval-Heywood correlation (`tribo_core::correlation`) beside Tribo's per-component
//! FMEP: the tables, CSV files and plots of `run --fmep`, `compare` and `sweep`.

use std::fmt::Write as _;

use crate::output::{OutputError, ResultDir};
use crate::sim::{Fmep, PlateauResult, RunResult};
use tribo_core::correlation::{beside, guard_band, Beside, Correlation};

/// The components of one plateau side by side (`None` if the plateau has no correlation):
/// each law's FMEP by the run's basis `fmep`, so a piston carrying ring and skirt laws is
/// also shown as rings and skirt.
pub fn plateau_rows(p: &PlateauResult, fmep: &Fmep) -> Option<Vec<Beside>> {
    let c = p.correlation.as_ref()?;
    Some(beside(
        p.joints.iter().map(|l| {
            (
                l.joint.as_str(),
                l.law.as_str(),
                fmep.kpa(l.friction_torque_nm),
            )
        }),
        c,
    ))
}

/// The components side by side from per-joint torques (a sweep point: its laws are not
/// known apart, so the pistons stay whole).
pub fn torque_rows<'a>(
    joints: impl Iterator<Item = (&'a str, f64)>,
    fmep: &Fmep,
    c: &Correlation,
) -> Vec<Beside> {
    let kpa: Vec<(&str, &str, f64)> = joints.map(|(j, t)| (j, "", fmep.kpa(t))).collect();
    beside(kpa.into_iter(), c)
}

fn num(x: Option<f64>, width: usize) -> String {
    match x {
        Some(v) => format!("{v:>width$.3}"),
        None => format!("{:>width$}", "-"),
    }
}

/// The heading: source, basis and the viscosity ratio, wrapped to the reports' width.
fn heading(basis: &str, c: &Correlation) -> String {
    let text = format!(
        "Beside the correlation: {} ({basis}, kPa; the rig's geometry and oil, mu/mu0 = {:.2})",
        c.source, c.viscosity_ratio
    );
    let wrapped = crate::report::wrap(&text, crate::report::MAX_COLUMNS, "  ");
    format!("\n{}", wrapped.trim_end_matches('\n'))
}

/// `run`: every plateau's components, Tribo beside the correlation, with the ratio.
pub fn run_text(r: &RunResult) -> String {
    let mut out = String::new();
    let Some(first) = r.plateaus.iter().find_map(|p| p.correlation.as_ref()) else {
        return out;
    };
    if r.plateaus.iter().all(|p| p.joints.is_empty()) {
        return out;
    }
    let _ = writeln!(out, "{}", heading(r.fmep.basis.formula(), first));
    let _ = writeln!(
        out,
        "{:>8}  {:<22} {:<12} {:>9} {:>11} {:>7}  terms",
        "set rpm", "component", "joints", "Tribo", "correlation", "ratio"
    );
    for p in &r.plateaus {
        let Some(rows) = plateau_rows(p, &r.fmep) else {
            continue;
        };
        for (k, row) in rows.iter().enumerate() {
            let rpm = if k == 0 {
                format!("{:.0}", p.set_speed_rpm)
            } else {
                String::new()
            };
            let cols = format!(
                "{rpm:>8}  {:<22} {:<12} {} {} {}",
                row.component,
                row.joints,
                num(row.tribo_kpa, 9),
                num(row.correlation_kpa, 11),
                row.ratio()
                    .map_or(format!("{:>7}", "-"), |x| format!("{x:>7.2}")),
            );
            // The terms beside the numbers where they fit; a longer note goes on its own
            // line(s) under the component column, so the numbers stay in their columns.
            let one_line = format!("{cols}  {}", row.note);
            if one_line.chars().count() <= crate::report::MAX_COLUMNS {
                let _ = writeln!(out, "{one_line}");
            } else {
                let _ = writeln!(out, "{}", cols.trim_end());
                let indent = " ".repeat(12);
                out.push_str(&crate::report::wrap(
                    &format!("{indent}{}", row.note),
                    crate::report::MAX_COLUMNS,
                    &indent,
                ));
            }
        }
        let band = guard_text(&rows);
        if !band.is_empty() {
            out.push_str(&crate::report::wrap(
                &format!("{:>8}  guard band: {band}", ""),
                crate::report::MAX_COLUMNS,
                &" ".repeat(22),
            ));
        }
    }
    out
}

/// The groups against their guard bands, one clause each (`total 0.79 in 0.70-1.30`, `... OUT
/// of ...`): the correlation judges the engine by its groups, never by a component.
fn guard_text(rows: &[Beside]) -> String {
    guard_band(rows)
        .iter()
        .map(|g| {
            format!(
                "{} {:.2} {} {:.2}-{:.2}",
                g.group,
                g.ratio,
                if g.inside { "in" } else { "OUT of" },
                g.band[0],
                g.band[1]
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// `fmep_correlation.csv` of `run --fmep`: one row per plateau and component.
pub fn run_csv(r: &RunResult) -> std::io::Result<String> {
    let mut rows = Vec::new();
    for p in &r.plateaus {
        for row in plateau_rows(p, &r.fmep).unwrap_or_default() {
            rows.push(csv_row(&[p.set_speed_rpm.to_string()], &row));
        }
    }
    crate::report::csv_text(&header(&["set_speed_rpm"]), rows)
}

/// One plateau's rows in `fmep_correlation.json`.
#[derive(serde::Serialize)]
struct PlateauRows {
    set_speed_rpm: f64,
    oil_temp_c: f64,
    rows: Vec<Beside>,
}

/// `fmep_correlation.json` of `run --fmep`: the rows of the table and the CSV per plateau, with
/// the ratio where both sides have a number.
pub fn run_json(r: &RunResult) -> std::io::Result<String> {
    let plateaus: Vec<serde_json::Value> = r
        .plateaus
        .iter()
        .filter_map(|p| {
            let rows = plateau_rows(p, &r.fmep)?;
            let guard = guard_band(&rows);
            let ratios: Vec<Option<f64>> = rows.iter().map(Beside::ratio).collect();
            let mut v = serde_json::to_value(PlateauRows {
                set_speed_rpm: p.set_speed_rpm,
                oil_temp_c: p.oil_temp_c,
                rows,
            })
            .ok()?;
            if let Some(rows) = v["rows"].as_array_mut() {
                for (row, ratio) in rows.iter_mut().zip(ratios) {
                    row["ratio"] = ratio.map_or(serde_json::Value::Null, serde_json::Value::from);
                }
            }
            v["guard_band"] = serde_json::to_value(guard).ok()?;
            Some(v)
        })
        .collect();
    let doc = serde_json::json!({ "basis": r.fmep.basis.formula(), "plateaus": plateaus });
    serde_json::to_string_pretty(&doc).map_err(std::io::Error::other)
}

/// A CSV header: the leading columns, then a row's.
fn header<'a>(lead: &[&'a str]) -> Vec<&'a str> {
    let mut h = lead.to_vec();
    h.extend([
        "component",
        "joints",
        "tribo_kpa",
        "correlation_kpa",
        "ratio",
        "terms",
    ]);
    h
}

/// A CSV row: the leading columns, then the components side by side.
fn csv_row(lead: &[String], row: &Beside) -> Vec<String> {
    // + 0.0: an empty sum (no law on any joint) is -0.0, written "-0"; it is plain 0.
    let opt = |x: Option<f64>| x.map_or(String::new(), |v| (v + 0.0).to_string());
    let mut v: Vec<String> = lead.to_vec();
    v.extend([
        row.component.clone(),
        row.joints.clone(),
        opt(row.tribo_kpa),
        opt(row.correlation_kpa),
        opt(row.ratio()),
        row.note.clone(),
    ]);
    v
}

/// The heading of a comparison's correlation text, from the first plateau that has the
/// correlation (none without one).
fn comparison_heading(c: &crate::study::Comparison) -> Option<String> {
    let first = c
        .sets
        .iter()
        .flat_map(|s| s.run.plateaus.iter())
        .find_map(|p| p.correlation.as_ref())?;
    Some(heading(c.sets[0].run.fmep.basis.formula(), first))
}

/// `compare`: per law set and plateau, the components both sides give a number for.
pub fn comparison_text(c: &crate::study::Comparison) -> String {
    let mut out = String::new();
    let Some(head) = comparison_heading(c) else {
        return out;
    };
    let _ = writeln!(out, "{head}");
    let speeds: Vec<f64> = c.sets[0]
        .run
        .plateaus
        .iter()
        .map(|p| p.set_speed_rpm)
        .collect();
    let per_plateau: Vec<Vec<Vec<Beside>>> = (0..speeds.len())
        .map(|i| {
            c.sets
                .iter()
                .map(|s| {
                    s.run
                        .plateaus
                        .get(i)
                        .and_then(|p| plateau_rows(p, &s.run.fmep))
                        .unwrap_or_default()
                })
                .collect()
        })
        .collect();
    // One table row per plateau and component the correlation gives a number for.
    let rows: Vec<(usize, usize, &Beside)> = per_plateau
        .iter()
        .enumerate()
        .flat_map(|(i, per_set)| {
            per_set
                .first()
                .into_iter()
                .flatten()
                .filter(|row| row.correlation_kpa.is_some())
                .enumerate()
                .map(move |(k, row)| (i, k, row))
        })
        .collect();
    let cw = rows
        .iter()
        .map(|(_, _, r)| r.component.chars().count())
        .chain(["component".len()])
        .max()
        .unwrap_or(0);
    let left_rows = rows
        .iter()
        .map(|&(i, k, row)| {
            let lead = if k == 0 {
                format!("{:.0}", speeds[i])
            } else {
                String::new()
            };
            format!(
                "{lead:>7}  {:<cw$} {}",
                row.component,
                num(row.correlation_kpa, 11)
            )
        })
        .collect();
    let blocks = c
        .sets
        .iter()
        .enumerate()
        .map(|(j, s)| {
            let found = |&(i, _, row): &(usize, usize, &Beside)| {
                per_plateau[i][j]
                    .iter()
                    .find(|r| r.component == row.component)
                    .filter(|r| r.tribo_kpa.is_some())
            };
            let tribo = rows
                .iter()
                .map(|r| {
                    found(r)
                        .and_then(|t| t.tribo_kpa)
                        .map_or("not modelled".into(), |v| format!("{v:.3}"))
                })
                .collect();
            let ratio = rows
                .iter()
                .map(|r| {
                    found(r)
                        .and_then(Beside::ratio)
                        .map_or("-".into(), |x| format!("{x:.2}x"))
                })
                .collect();
            (s.lawset.clone(), vec![("Tribo", tribo), ("ratio", ratio)])
        })
        .collect();
    let table = crate::report::Blocks {
        left_header: [
            String::new(),
            format!("{:>7}  {:<cw$} {:>11}", "rpm", "component", "correlation"),
        ],
        left_rows,
        blocks,
    };
    out.push_str(&table.render());
    out
}

/// `compare` without `--correlation`: the correlation in a few lines, one per law set: the
/// range of Tribo's total over the correlation's, and at the speed where Tribo falls furthest
/// below it, the component that carries most of the missing friction (one the rig does not
/// model counts in full). The whole table is in `correlation.csv` and under `--correlation`.
pub fn comparison_summary(c: &crate::study::Comparison) -> String {
    let mut out = String::new();
    let Some(head) = comparison_heading(c) else {
        return out;
    };
    let _ = writeln!(out, "{head}");
    for s in &c.sets {
        let rows: Vec<(f64, Vec<Beside>)> = s
            .run
            .plateaus
            .iter()
            .filter_map(|p| Some((p.set_speed_rpm, plateau_rows(p, &s.run.fmep)?)))
            .collect();
        let totals: Vec<(f64, f64, f64)> = rows
            .iter()
            .filter_map(|(rpm, r)| {
                let t = r.iter().find(|b| b.component == "total")?;
                Some((*rpm, t.tribo_kpa?, t.correlation_kpa?))
            })
            .collect();
        let ratios: Vec<f64> = totals
            .iter()
            .filter(|t| t.2 > 0.0)
            .map(|t| t.1 / t.2)
            .collect();
        if ratios.is_empty() {
            continue;
        }
        let lo = ratios.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = ratios.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let mut line = format!("  {}: total {lo:.2}-{hi:.2}x the correlation's", s.lawset);
        let worst = totals
            .iter()
            .zip(&rows)
            .filter(|(t, _)| t.2 > t.1)
            .max_by(|a, b| (a.0 .2 - a.0 .1).total_cmp(&(b.0 .2 - b.0 .1)));
        match worst {
            Some(((rpm, tribo, corr), (_, parts))) => {
                let short = parts
                    .iter()
                    .filter(|b| {
                        !matches!(b.component.as_str(), "total" | "reciprocating")
                            && !b.component.contains("ring")
                            && !b.component.contains("skirt")
                    })
                    .filter_map(|b| {
                        let corr = b.correlation_kpa?;
                        Some((b, corr - b.tribo_kpa.unwrap_or(0.0)))
                    })
                    .max_by(|a, b| a.1.total_cmp(&b.1));
                let _ = write!(line, "; at {rpm:.0} rpm {:.1} kPa below it", corr - tribo);
                if let Some((b, gap)) = short.filter(|x| x.1 > 0.0) {
                    let _ = write!(
                        line,
                        ", most of that in {} ({gap:.1} kPa{})",
                        b.component,
                        if b.tribo_kpa.is_none() {
                            ", not modelled"
                        } else {
                            ""
                        }
                    );
                }
            }
            None => line.push_str(", never below it"),
        }
        out.push_str(&crate::report::wrap(
            &line,
            crate::report::MAX_COLUMNS,
            "      ",
        ));
    }
    out.push_str("  (every component and speed: correlation.csv, or --correlation)\n");
    out
}

/// `correlation.csv` of `compare --out`: law set, plateau, component.
pub fn comparison_csv(c: &crate::study::Comparison) -> std::io::Result<String> {
    let mut rows = Vec::new();
    for s in &c.sets {
        for p in &s.run.plateaus {
            for row in plateau_rows(p, &s.run.fmep).unwrap_or_default() {
                rows.push(csv_row(
                    &[s.lawset.clone(), p.set_speed_rpm.to_string()],
                    &row,
                ));
            }
        }
    }
    crate::report::csv_text(&header(&["lawset", "set_speed_rpm"]), rows)
}

/// The rows of a sweep point (`None` without a correlation).
fn sweep_rows(s: &crate::study::Sweep, p: &crate::study::SweepPoint) -> Option<Vec<Beside>> {
    let c = p.correlation.as_ref()?;
    Some(torque_rows(
        p.joints
            .iter()
            .map(|j| (j.joint.as_str(), j.friction_torque_nm)),
        &s.fmep,
        c,
    ))
}

/// `sweep`: per law set, temperature and speed, the components both sides give a number for.
pub fn sweep_text(s: &crate::study::Sweep) -> String {
    let mut out = String::new();
    let Some(first) = s
        .sets
        .iter()
        .flat_map(|x| x.points.iter())
        .find_map(|p| p.correlation.as_ref())
    else {
        return out;
    };
    let _ = writeln!(out, "{}", heading(s.fmep.basis.formula(), first));
    // The groups the correlation is judged by (its components are in sweep_correlation.csv).
    const COMPONENTS: [&str; 3] = ["crankshaft", "reciprocating", "total"];
    for set in &s.sets {
        let points: Vec<(&crate::study::SweepPoint, Vec<Beside>)> = set
            .points
            .iter()
            .filter_map(|p| Some((p, sweep_rows(s, p)?)))
            .collect();
        let _ = writeln!(
            out,
            "\n{}: FMEP, kPa: Tribo beside the correlation (corr.)",
            set.lawset
        );
        let cell = |rows: &[Beside], name: &str, pick: fn(&Beside) -> Option<f64>| {
            rows.iter()
                .find(|r| r.component == name)
                .and_then(pick)
                .map_or("-".to_string(), |v| format!("{v:.3}"))
        };
        let blocks = COMPONENTS
            .iter()
            .map(|&name| {
                let column = |pick: fn(&Beside) -> Option<f64>| {
                    points
                        .iter()
                        .map(|(_, rows)| cell(rows, name, pick))
                        .collect()
                };
                (
                    name.to_string(),
                    vec![
                        ("Tribo", column(|r| r.tribo_kpa)),
                        ("corr.", column(|r| r.correlation_kpa)),
                    ],
                )
            })
            .collect();
        let table = crate::report::Blocks {
            left_header: [String::new(), format!("{:>7} {:>7}", "oil C", "rpm")],
            left_rows: points
                .iter()
                .map(|(p, _)| format!("{:>7.1} {:>7.0}", p.oil_temp_c, p.speed_rpm))
                .collect(),
            blocks,
        };
        out.push_str(&table.render());
    }
    out
}

/// `sweep_correlation.csv` of `sweep --out`: law set, temperature, speed, component.
pub fn sweep_csv(s: &crate::study::Sweep) -> std::io::Result<String> {
    let mut rows = Vec::new();
    for set in &s.sets {
        for p in &set.points {
            for row in sweep_rows(s, p).unwrap_or_default() {
                rows.push(csv_row(
                    &[
                        set.lawset.clone(),
                        p.oil_temp_c.to_string(),
                        p.speed_rpm.to_string(),
                    ],
                    &row,
                ));
            }
        }
    }
    crate::report::csv_text(&header(&["lawset", "oil_temp_c", "speed_rpm"]), rows)
}

/// A rendered file's text, or the error naming it.
fn rendered(what: &str, r: std::io::Result<String>) -> Result<String, OutputError> {
    r.map_err(|error| OutputError::Render {
        what: what.to_string(),
        error,
    })
}

/// `run --fmep`: `fmep_correlation.csv`, `.json` and `.svg` into the result set.
pub fn write_run(r: &RunResult, out: &mut ResultDir) -> Result<(), OutputError> {
    if r.plateaus.iter().all(|p| p.correlation.is_none()) {
        return Ok(());
    }
    out.write(
        "fmep_correlation.csv",
        rendered("fmep_correlation.csv", run_csv(r))?.as_bytes(),
    )?;
    out.write(
        "fmep_correlation.json",
        rendered("fmep_correlation.json", run_json(r))?.as_bytes(),
    )?;
    out.write(
        "fmep_correlation.svg",
        rendered("fmep_correlation.svg", run_svg(r, None))?.as_bytes(),
    )
}

/// `compare --out`: `correlation.csv` and `correlation_<lawset>.svg` per law set.
pub fn write_comparison(
    c: &crate::study::Comparison,
    out: &mut ResultDir,
) -> Result<(), OutputError> {
    out.write(
        "correlation.csv",
        rendered("correlation.csv", comparison_csv(c))?.as_bytes(),
    )?;
    for s in &c.sets {
        let name = format!("correlation_{}.svg", crate::plots::file_stem(&s.lawset));
        out.write(
            &name,
            rendered(&name, run_svg(&s.run, Some(&s.lawset)))?.as_bytes(),
        )?;
    }
    Ok(())
}

/// `sweep --out`: `sweep_correlation.csv`.
pub fn write_sweep(s: &crate::study::Sweep, out: &mut ResultDir) -> Result<(), OutputError> {
    out.write(
        "sweep_correlation.csv",
        rendered("sweep_correlation.csv", sweep_csv(s))?.as_bytes(),
    )
}

/// The components both sides model, for the plots.
/// (rings and skirt where the pistons carry ring and skirt laws; rows a run lacks are left out).
const PLOTTED: [&str; 7] = [
    "main bearings",
    "rod bearings",
    "pistons",
    "piston rings",
    "piston skirt",
    "reciprocating",
    "total",
];

/// `fmep_correlation.svg` of `run --fmep` (`lawset` `None`) or `correlation_<lawset>.svg` of
/// `compare`: Tribo's and the correlation's FMEP per component against speed, the law set named
/// in the title where the run is one of several.
pub fn run_svg(r: &RunResult, lawset: Option<&str>) -> std::io::Result<String> {
    let speeds: Vec<f64> = r.plateaus.iter().map(|p| p.set_speed_rpm).collect();
    let rows: Vec<Vec<Beside>> = r
        .plateaus
        .iter()
        .map(|p| plateau_rows(p, &r.fmep).unwrap_or_default())
        .collect();
    let series = PLOTTED
        .iter()
        .map(|name| {
            let get = |f: fn(&Beside) -> Option<f64>| -> Vec<Option<f64>> {
                rows.iter()
                    .map(|rs| rs.iter().find(|x| x.component == *name).and_then(f))
                    .collect()
            };
            (
                name.to_string(),
                speeds.clone(),
                get(|b| b.tribo_kpa),
                get(|b| b.correlation_kpa),
            )
        })
        .filter(|(_, _, tribo, corr)| tribo.iter().chain(corr).any(Option::is_some))
        .collect::<Vec<_>>();
    let run = match lawset {
        Some(set) => format!("{}, {set}", r.rig),
        None => r.rig.clone(),
    };
    crate::plots::correlation_svg(
        &format!("FMEP vs crank speed, {run}: Tribo beside Sandoval-Heywood"),
        &series,
    )
}
