//! The studies users come for: a side-by-side comparison of law sets against measurements, and
//! the data they run on.

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::Serialize;
use tribo_plugin_api::loader::LawRegistry;

use crate::cycle::Segment;
use crate::lawset::LawSet;
use crate::rig::{Rig, RigError, Temperature};
use crate::sim::{RunResult, SimError, Simulation};

/// Why a study failed.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// A rig or law-set problem.
    #[error(transparent)]
    Rig(#[from] Box<RigError>),
    /// A run failed.
    // The run's message is part of this one and not also a `source`: the CLI prints the
    // chain of sources, which repeated it.
    #[error("law set `{lawset}`: {error}")]
    Run {
        /// Law set.
        lawset: String,
        /// The failure.
        error: Box<SimError>,
    },
    /// A data file problem.
    #[error("{file}{}: {message}", line.map(|l| format!(":{l}")).unwrap_or_default())]
    Data {
        /// File.
        file: PathBuf,
        /// Line, if known.
        line: Option<u64>,
        /// What is wrong.
        message: String,
    },
}

/// One measured point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DataRow {
    /// Engine speed, rpm.
    pub speed_rpm: f64,
    /// Measured motoring torque, N m.
    pub torque_nm: f64,
    /// Oil temperature, C.
    pub oil_temp_c: f64,
}

/// Read a `speed_rpm,torque_nm,oil_temp_c` CSV from disk, or a bundled data file by name.
/// Lines starting with `#` are comments (sources).
pub fn read_data(arg: &str) -> Result<(PathBuf, Vec<DataRow>), StudyError> {
    let path = PathBuf::from(arg);
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) => match crate::bundled::data(arg) {
            Some(t) => {
                let name = PathBuf::from(format!("<bundled>/{}", crate::bundled::file_name(arg)));
                return parse_data(&name, t).map(|r| (name, r));
            }
            None => {
                return Err(StudyError::Data {
                    file: path,
                    line: None,
                    message: format!("cannot read the data file: {e}"),
                })
            }
        },
    };
    parse_data(&path, &text).map(|r| (path, r))
}

/// Parse data text (see [`read_data`]).
pub fn parse_data(path: &Path, text: &str) -> Result<Vec<DataRow>, StudyError> {
    let err = |line: Option<u64>, message: String| StudyError::Data {
        file: path.to_path_buf(),
        line,
        message,
    };
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let headers = reader
        .headers()
        .map_err(|e| err(None, e.to_string()))?
        .clone();
    let col = |name: &str| {
        headers.iter().position(|h| h == name).ok_or_else(|| {
            err(None, format!("missing column `{name}`; expected the columns speed_rpm,torque_nm,oil_temp_c (found: {})", headers.iter().collect::<Vec<_>>().join(",")))
        })
    };
    let (cs, ct, co) = (col("speed_rpm")?, col("torque_nm")?, col("oil_temp_c")?);
    let mut rows = Vec::new();
    for rec in reader.records() {
        let rec = rec.map_err(|e| err(e.position().map(|p| p.line()), e.to_string()))?;
        let line = rec.position().map(|p| p.line());
        let num = |i: usize, name: &str| -> Result<f64, StudyError> {
            let cell = rec.get(i).unwrap_or("");
            cell.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| {
                    err(
                        line,
                        format!(
                            "column `{name}` (column {}): `{cell}` is not a number",
                            i + 1
                        ),
                    )
                })
        };
        let row = DataRow {
            speed_rpm: num(cs, "speed_rpm")?,
            torque_nm: num(ct, "torque_nm")?,
            oil_temp_c: num(co, "oil_temp_c")?,
        };
        if row.speed_rpm <= 0.0 {
            return Err(err(
                line,
                format!("speed_rpm must be positive, got {}", row.speed_rpm),
            ));
        }
        rows.push(row);
    }
    if rows.is_empty() {
        return Err(err(None, "no data rows".into()));
    }
    rows.sort_by(|a, b| a.speed_rpm.total_cmp(&b.speed_rpm));
    if rows.windows(2).any(|w| w[0].speed_rpm == w[1].speed_rpm) {
        return Err(err(None, "two rows have the same speed".into()));
    }
    Ok(rows)
}

/// The thesis's cycle pattern through the data's speeds: 1.5 s up to the first speed, then 0.5 s
/// ramps between speeds, each held 1 s (thesis 9.1.1).
pub fn cycle_through(rows: &[DataRow]) -> Vec<Segment> {
    let mut s = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        s.push(Segment::Ramp {
            to_rpm: r.speed_rpm,
            duration_s: if i == 0 { 1.5 } else { 0.5 },
        });
        s.push(Segment::Hold { duration_s: 1.0 });
    }
    s
}

/// `rig` with `lawset` attached, and, with data, the cycle through the data's speeds at the
/// data's oil temperatures.
pub fn prepare(rig: &Rig, lawset: &LawSet, data: Option<&[DataRow]>) -> Result<Rig, Box<RigError>> {
    let mut r = rig.clone();
    lawset.apply(&mut r);
    if let Some(rows) = data {
        r.file.cycle.segments = Some(cycle_through(rows));
        r.file.oil.temperature_c =
            Temperature::PerPlateau(rows.iter().map(|x| x.oil_temp_c).collect());
        r.overridden.push("cycle".into());
        r.overridden.push("oil.temperature_c".into());
        crate::rig::revalidate(&r)?;
    }
    Ok(r)
}

/// Run one rig (steady-state or full cycle).
pub fn run_rig(rig: &Rig, registry: &LawRegistry, steady: bool) -> Result<RunResult, SimError> {
    let mut sim = Simulation::new(rig, registry)?;
    if steady {
        sim.run_steady()
    } else {
        sim.run(None)
    }
}

/// One law set's results against the data.
#[derive(Debug, Clone, Serialize)]
pub struct SetResult {
    /// Law-set name.
    pub lawset: String,
    /// Its file.
    pub file: String,
    /// The run.
    pub run: RunResult,
    /// Model minus measurement at each speed, N m.
    pub errors_nm: Vec<f64>,
    /// Root-mean-square error, N m.
    pub rmse_nm: f64,
    /// Largest absolute error, N m.
    pub max_abs_error_nm: f64,
}

/// A side-by-side comparison.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    /// Rig name.
    pub rig: String,
    /// Data file.
    pub data_file: String,
    /// The measurements.
    pub data: Vec<DataRow>,
    /// `steady` or `transient`.
    pub mode: String,
    /// Each law set.
    pub sets: Vec<SetResult>,
}

/// RMSE and largest absolute error of `model` against `measured`.
pub fn errors(model: &[f64], measured: &[f64]) -> (Vec<f64>, f64, f64) {
    let e: Vec<f64> = model.iter().zip(measured).map(|(m, d)| m - d).collect();
    let rmse = (e.iter().map(|x| x * x).sum::<f64>() / e.len().max(1) as f64).sqrt();
    let max = e.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
    (e, rmse, max)
}

/// Run every law set on `rig` at the data's speeds and temperatures, in parallel. The order of
/// the results is the order of `lawsets`, whatever the scheduling.
pub fn compare(
    rig: &Rig,
    lawsets: &[LawSet],
    data_file: &Path,
    data: &[DataRow],
    registry: &LawRegistry,
    steady: bool,
) -> Result<Comparison, StudyError> {
    let measured: Vec<f64> = data.iter().map(|r| r.torque_nm).collect();
    let sets = lawsets
        .par_iter()
        .map(|ls| {
            let r = prepare(rig, ls, Some(data))?;
            let run = run_rig(&r, registry, steady).map_err(|e| StudyError::Run {
                lawset: ls.name().into(),
                error: Box::new(e),
            })?;
            let model: Vec<f64> = run.plateaus.iter().map(|p| p.motoring_torque_nm).collect();
            let (errors_nm, rmse_nm, max_abs_error_nm) = errors(&model, &measured);
            Ok(SetResult {
                lawset: ls.name().into(),
                file: ls.path.display().to_string(),
                run,
                errors_nm,
                rmse_nm,
                max_abs_error_nm,
            })
        })
        .collect::<Result<Vec<_>, StudyError>>()?;
    Ok(Comparison {
        rig: rig.file.name.clone(),
        data_file: data_file.display().to_string(),
        data: data.to_vec(),
        mode: if steady {
            "steady".into()
        } else {
            "transient".into()
        },
        sets,
    })
}

/// Which body a mass study scales.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum ScaledBody {
    /// The connecting rod (mass and inertia).
    Rod,
    /// The piston assembly (mass).
    Piston,
    /// The crankshaft (mass and inertia).
    Crank,
}

/// `rig` with `body`'s mass (and inertia) scale factors multiplied by `scale`.
pub fn scaled(rig: &Rig, body: ScaledBody, scale: f64) -> Result<Rig, Box<RigError>> {
    let mut r = rig.clone();
    let b = &mut r.file.bodies;
    match body {
        ScaledBody::Rod => {
            b.rod.mass_scale *= scale;
            b.rod.inertia_scale *= scale;
        }
        ScaledBody::Piston => b.piston.mass_scale *= scale,
        ScaledBody::Crank => {
            b.crank.mass_scale *= scale;
            b.crank.inertia_scale *= scale;
        }
    }
    r.overridden.push("bodies".into());
    crate::rig::revalidate(&r)?;
    Ok(r)
}

/// One joint's and law's response to the scaling at one speed.
#[derive(Debug, Clone, Serialize)]
pub struct JointChange {
    /// Joint.
    pub joint: String,
    /// Law.
    pub law: String,
    /// Friction torque, original rig, N m.
    pub original_nm: f64,
    /// Friction torque, scaled rig, N m.
    pub scaled_nm: f64,
    /// Change of the friction torque, N m.
    pub change_nm: f64,
    /// Change of the joint's mean normal load, N.
    pub normal_load_change_n: f64,
}

/// The response at one speed and scale.
#[derive(Debug, Clone, Serialize)]
pub struct SpeedChange {
    /// Speed, rpm.
    pub speed_rpm: f64,
    /// Scale factor.
    pub scale: f64,
    /// Motoring torque, original, N m.
    pub original_nm: f64,
    /// Motoring torque, scaled, N m.
    pub scaled_nm: f64,
    /// Change, N m.
    pub change_nm: f64,
    /// FEDEM's change for the same speed (table 10.6 minus 10.5, rod at 0.6), N m.
    pub fedem_change_nm: Option<f64>,
    /// Per joint and law.
    pub joints: Vec<JointChange>,
}

/// One law set's mass response.
#[derive(Debug, Clone, Serialize)]
pub struct MassResponse {
    /// Law set.
    pub lawset: String,
    /// Body scaled.
    pub body: ScaledBody,
    /// Per scale and speed.
    pub changes: Vec<SpeedChange>,
}

/// Torque change per speed and joint when `body` is scaled by each of `scales`, for each law
/// set, against the unscaled rig. Runs in parallel; results in input order.
#[allow(clippy::too_many_arguments)]
pub fn mass_response(
    rig: &Rig,
    lawsets: &[LawSet],
    body: ScaledBody,
    scales: &[f64],
    registry: &LawRegistry,
    steady: bool,
    fedem: Option<&[(f64, f64)]>,
) -> Result<Vec<MassResponse>, StudyError> {
    let jobs: Vec<(usize, Option<f64>)> = (0..lawsets.len())
        .flat_map(|i| std::iter::once((i, None)).chain(scales.iter().map(move |s| (i, Some(*s)))))
        .collect();
    let runs = jobs
        .par_iter()
        .map(|(i, s)| {
            let ls = &lawsets[*i];
            let base = prepare(rig, ls, None)?;
            let r = match s {
                Some(s) => scaled(&base, body, *s)?,
                None => base,
            };
            run_rig(&r, registry, steady).map_err(|e| StudyError::Run {
                lawset: ls.name().into(),
                error: Box::new(e),
            })
        })
        .collect::<Result<Vec<RunResult>, StudyError>>()?;
    let per_set = scales.len() + 1;
    let mut out = Vec::new();
    for (i, ls) in lawsets.iter().enumerate() {
        let original = &runs[i * per_set];
        let mut changes = Vec::new();
        for (k, s) in scales.iter().enumerate() {
            let run = &runs[i * per_set + 1 + k];
            for (p0, p1) in original.plateaus.iter().zip(&run.plateaus) {
                let joints = p0
                    .joints
                    .iter()
                    .zip(&p1.joints)
                    .map(|(a, b)| JointChange {
                        joint: a.joint.clone(),
                        law: a.law.clone(),
                        original_nm: a.friction_torque_nm,
                        scaled_nm: b.friction_torque_nm,
                        change_nm: b.friction_torque_nm - a.friction_torque_nm,
                        normal_load_change_n: b.mean_normal_load_n - a.mean_normal_load_n,
                    })
                    .collect();
                let fedem_change_nm = fedem.and_then(|f| {
                    f.iter()
                        .find(|(rpm, _)| (rpm - p0.set_speed_rpm).abs() < 0.5)
                        .map(|(_, d)| *d)
                });
                changes.push(SpeedChange {
                    speed_rpm: p0.set_speed_rpm,
                    scale: *s,
                    original_nm: p0.motoring_torque_nm,
                    scaled_nm: p1.motoring_torque_nm,
                    change_nm: p1.motoring_torque_nm - p0.motoring_torque_nm,
                    fedem_change_nm: if (*s - 0.6).abs() < 1e-9 {
                        fedem_change_nm
                    } else {
                        None
                    },
                    joints,
                });
            }
        }
        out.push(MassResponse {
            lawset: ls.name().into(),
            body,
            changes,
        });
    }
    Ok(out)
}

/// FEDEM's torque change with the rod at 60% per speed: table 10.6 minus table 10.5.
pub fn fedem_rod_change() -> Vec<(f64, f64)> {
    // The FEDEM tables have `speed_rpm,sim_speed_rad_s,torque_nm` (no oil temperature), so they
    // are read by column name here rather than through `parse_data`.
    let read = |name: &str| -> Vec<(f64, f64)> {
        let Some(text) = crate::bundled::data(name) else {
            return Vec::new();
        };
        let mut reader = csv::ReaderBuilder::new()
            .comment(Some(b'#'))
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes());
        let Ok(headers) = reader.headers().cloned() else {
            return Vec::new();
        };
        let col = |n: &str| headers.iter().position(|h| h == n);
        let (Some(cs), Some(ct)) = (col("speed_rpm"), col("torque_nm")) else {
            return Vec::new();
        };
        reader
            .records()
            .filter_map(|r| {
                let r = r.ok()?;
                Some((r.get(cs)?.parse().ok()?, r.get(ct)?.parse().ok()?))
            })
            .collect()
    };
    let (a, b) = (read("fedem-tuned.csv"), read("fedem-light-rod.csv"));
    a.iter()
        .zip(&b)
        .map(|((rpm, t0), (_, t1))| (*rpm, t1 - t0))
        .collect()
}
