//! The studies users come for: a side-by-side comparison of law sets against measurements, and
//! the data they run on.

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tribo_plugin_api::loader::LawRegistry;

use crate::fit::TorqueModel;
use crate::score::{self, Scores, TemperatureResponse, Validation};
use crate::uncertainty::Uncertainty;
use tribo_config::lawset::{FreeParam, LawSet};
use tribo_config::rig::{readable, Rig, RigError, Temperature};
use tribo_core::cycle::Segment;
use tribo_core::sim::{RunResult, SimError};

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
    /// A law set's laws cannot be bound on the rig (an unknown law, a misspelled or
    /// out-of-range parameter): found by [`check_lawsets`] before any run starts.
    #[error("law set `{lawset}`: {error}")]
    Laws {
        /// Law set.
        lawset: String,
        /// Where and what (the law-set file's line and column, or the `--law` argument).
        error: Box<SimError>,
    },
    /// A sweep's temperatures or speeds are unusable.
    #[error(transparent)]
    Input(#[from] SweepInputError),
    /// Two law sets of one study share a name (their results and plots would overwrite each
    /// other).
    #[error("two law sets are named `{name}` ({} and {}); every law set in one run needs its own name, as it names the result rows and plot files: rename one (its `name = ...` line)", first.display(), second.display())]
    DuplicateLawSet {
        /// The shared name.
        name: String,
        /// The first file with it.
        first: PathBuf,
        /// The second file with it.
        second: PathBuf,
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

/// Refuse two law sets with one name in one study: their result rows and plot files would
/// overwrite each other.
pub fn check_unique_names(lawsets: &[LawSet]) -> Result<(), StudyError> {
    for (j, b) in lawsets.iter().enumerate() {
        if let Some(a) = lawsets[..j].iter().find(|a| a.name() == b.name()) {
            return Err(StudyError::DuplicateLawSet {
                name: b.name().to_string(),
                first: a.path.clone(),
                second: b.path.clone(),
            });
        }
    }
    Ok(())
}

/// Whether law-set entry joint `entry` is among the joints `--law` names with `given`: the same
/// name, or, when `given` names a kind of joint (`piston`, `piston_*`), every joint of that kind.
fn law_arg_covers(given: &str, entry: &str) -> bool {
    /// The kind of a joint name: `piston` for `piston`, `piston_3` and `piston_*`.
    fn kind(j: &str) -> &str {
        match j.rsplit_once('_') {
            Some((k, n)) if n == "*" || n.parse::<usize>().is_ok() => k,
            _ => j,
        }
    }
    given == entry || (kind(given) == given.trim_end_matches("_*") && kind(entry) == kind(given))
}

/// The set `compare --law` adds: `base` with each `--law JOINT=LAW[:PARAMS]`'s law in place of
/// the base's laws on that joint (so the new law is compared, not added on top of another), named
/// `name` or, by default, after the laws (joined by `_`). The base's record of a tuning to
/// measured data (`prior_fit`) is dropped: those numbers were tuned with other laws.
pub fn set_with_laws(
    base: &LawSet,
    laws: &[String],
    name: Option<&str>,
) -> Result<LawSet, StudyError> {
    let mut parsed = Vec::with_capacity(laws.len());
    for arg in laws {
        parsed.push(tribo_config::rig::parse_law_arg(arg).map_err(Box::new)?);
    }
    let default_name = parsed
        .iter()
        .map(|p| p.law.law.as_str())
        .collect::<Vec<_>>()
        .join("_");
    let name = name.unwrap_or(&default_name).to_string();
    if let Err(why) = tribo_config::lawset::check_name(&name) {
        return Err(StudyError::Rig(Box::new(RigError {
            file: PathBuf::from("--name"),
            line: None,
            column: None,
            field: name.clone(),
            message: format!(
                "the new law set's name {why}; it names result rows and plot files, so it must be 1 to {} characters of ASCII letters, digits, `-`, `_` and `.` (give one with --name)",
                tribo_config::lawset::MAX_NAME_LEN
            ),
        })));
    }
    let mut file = base.file.clone();
    file.laws
        .retain(|e| !parsed.iter().any(|p| law_arg_covers(&p.joint, &e.joint)));
    let replaced: Vec<&str> = parsed.iter().map(|p| p.joint.as_str()).collect();
    file.description = format!(
        "{} with {} on {} in place of its laws there",
        base.name(),
        parsed
            .iter()
            .map(|p| p.law.law.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        replaced.join(", ")
    );
    file.name = name;
    file.prior_fit = None;
    let text = toml::to_string(&file).map_err(|e| {
        StudyError::Rig(Box::new(RigError {
            file: base.path.clone(),
            line: None,
            column: None,
            field: "(law set)".into(),
            message: format!("cannot write the law set with --law: {e}"),
        }))
    })?;
    let path = PathBuf::from(format!("<--law on {}>", base.path.display()));
    let mut set = LawSet::from_text(&path, &text).map_err(Box::new)?;
    set.add_law_args(laws).map_err(Box::new)?;
    Ok(set)
}

/// Check every law set of a study against the rig and the loaded laws before anything runs:
/// distinct names ([`check_unique_names`]), and every law of every set bound on `rig` (its law
/// found in `registry`, its parameters checked against the law's declaration and by the law
/// itself, its state allocated). An error is located in the law-set file (`FILE:line:column:
/// laws[i] (joint J, law L): parameter ...`) or at the `--law` argument (and its parameter
/// file). Binding takes milliseconds, so a bad third set fails at once, with no results
/// written. Free parameters are resolved by the studies themselves.
pub fn check_lawsets(
    rig: &Rig,
    lawsets: &[LawSet],
    registry: &LawRegistry,
) -> Result<(), StudyError> {
    check_each(rig, lawsets, registry, |r| {
        tribo_config::rig::simulation(r, registry).map(drop)
    })
}

/// [`check_lawsets`] without creating any law instance: names unique, every law known and its
/// parameters' names, types and ranges right, located in the law-set file. Only descriptions are
/// read, so no law code runs; the check a study runs before starting isolated workers.
pub fn check_lawsets_described(
    rig: &Rig,
    lawsets: &[LawSet],
    registry: &LawRegistry,
) -> Result<(), StudyError> {
    check_each(rig, lawsets, registry, |r| {
        tribo_config::rig::check_laws(r, registry)
    })
}

/// Unique names, then `check` on `rig` prepared with each law set, its error named by the set,
/// and its free parameters resolved against the laws' declarations (bounds inside each law's
/// own range).
fn check_each(
    rig: &Rig,
    lawsets: &[LawSet],
    registry: &LawRegistry,
    check: impl Fn(&Rig) -> Result<(), SimError>,
) -> Result<(), StudyError> {
    check_unique_names(lawsets)?;
    for ls in lawsets {
        let r = prepare(rig, ls, None)?;
        check(&r).map_err(|e| StudyError::Laws {
            lawset: ls.name().into(),
            error: Box::new(e),
        })?;
        if ls.file.laws.iter().any(|e| !e.free.is_empty()) {
            ls.free_params(registry, None).map_err(Box::new)?;
        }
    }
    Ok(())
}

/// Check that `rig` can run the cycle a data run makes (its speeds held long enough for the
/// rig's measurement window, its oil temperatures in range): what [`prepare`] does for every
/// run, done once before any run starts.
pub fn check_data(rig: &Rig, data: &DataRun) -> Result<(), StudyError> {
    let mut r = rig.clone();
    run_through(&mut r, &data.rows).map_err(|mut e| {
        // The cycle is the data file's, whatever the rig's own fields say.
        e.file = data.file.clone();
        e.line = None;
        e.column = None;
        e
    })?;
    Ok(())
}

/// One measured point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DataRow {
    /// Engine speed, rpm.
    pub speed_rpm: f64,
    /// Measured motoring torque, N m.
    pub torque_nm: f64,
    /// Oil temperature, C.
    pub oil_temp_c: f64,
}

/// One measured run: a data file's points (distinct speeds, each at its own oil temperature).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct DataRun {
    /// The data file (or `<bundled>/NAME`).
    pub file: PathBuf,
    /// Its points, sorted by speed.
    pub rows: Vec<DataRow>,
    /// What the file declares about itself: the rig it was measured on, its noise.
    #[serde(default)]
    pub meta: DataMeta,
}

impl DataRun {
    /// Read a data run from a file or a bundled data file by name (see [`read_data`]), with
    /// what its comment lines declare ([`parse_meta`]).
    pub fn read(arg: &str) -> Result<Self, StudyError> {
        let (file, text) = data_text(arg)?;
        let rows = parse_data(&file, &text)?;
        let meta = parse_meta(&file, &text)?;
        Ok(Self { file, rows, meta })
    }

    /// The same file and declarations with other rows (a subset, or shifted temperatures).
    pub fn with_rows(&self, rows: Vec<DataRow>) -> Self {
        Self {
            file: self.file.clone(),
            rows,
            meta: self.meta.clone(),
        }
    }
}

/// What a data file declares about itself in comment lines of the form `# key: value`, so a
/// study can tell which rig the data belong to and how noisy they are. Other comment lines are
/// free text (sources), and only these keys are read.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DataMeta {
    /// The rig the data were measured on, by its `name` (`# rig: crf250r-motored`). A study on
    /// another rig refuses the file unless told the data apply to any rig.
    pub rig: Option<String>,
    /// The measurement's noise, one standard deviation, N m (`# noise_nm: 0.05`): the verdict
    /// of `compare` says whether a set predicts the data within it.
    pub noise_nm: Option<f64>,
}

/// The `# rig:` and `# noise_nm:` declarations of a data file's text (see [`DataMeta`]); a
/// declared noise that is not a positive number is an error at its line.
pub fn parse_meta(path: &Path, text: &str) -> Result<DataMeta, StudyError> {
    let mut meta = DataMeta::default();
    for (i, line) in text.lines().enumerate() {
        let Some(comment) = line.trim_start_matches('\u{feff}').trim().strip_prefix('#') else {
            continue;
        };
        let Some((key, value)) = comment.split_once(':') else {
            continue;
        };
        let value = value.trim();
        match key.trim() {
            "rig" if !value.is_empty() => meta.rig = Some(value.to_string()),
            "noise_nm" => {
                let noise = value.split_whitespace().next().unwrap_or("");
                match noise.parse::<f64>() {
                    Ok(x) if x.is_finite() && x > 0.0 => meta.noise_nm = Some(x),
                    _ => {
                        return Err(StudyError::Data {
                            file: path.to_path_buf(),
                            line: Some(i as u64 + 1),
                            message: format!(
                                "`# noise_nm: {value}`: the measurement noise must be a positive number of N m (one standard deviation), e.g. `# noise_nm: 0.05`"
                            ),
                        })
                    }
                }
            }
            _ => {}
        }
    }
    Ok(meta)
}

/// The bundled data file measured on rig `rig_name` (the first whose `# rig:` names it), if
/// any: what a study compares against when no data are given.
pub fn bundled_data_for(rig_name: &str) -> Option<&'static str> {
    tribo_config::bundled::data_names()
        .into_iter()
        .find(|name| {
            tribo_config::bundled::data(name)
                .and_then(|text| parse_meta(Path::new(name), text).ok())
                .is_some_and(|m| m.rig.as_deref() == Some(rig_name))
        })
}

/// The data a study on `rig` compares against when none are given: the bundled measurements
/// made on that rig ([`bundled_data_for`]). A rig without any is an error asking for data: no
/// bundled data are used on a rig they were not measured on.
pub fn default_data(rig: &Rig) -> Result<&'static str, StudyError> {
    bundled_data_for(&rig.file.name)
        .or_else(|| rig.file.measured_as.as_deref().and_then(bundled_data_for))
        .ok_or_else(|| {
        let measured: Vec<String> = tribo_config::bundled::data_names()
            .into_iter()
            .filter_map(|n| {
                let meta = parse_meta(Path::new(n), tribo_config::bundled::data(n)?).ok()?;
                Some(format!("{} ({n})", meta.rig?))
            })
            .collect();
        StudyError::Data {
            file: PathBuf::from("--data"),
            line: None,
            message: format!(
                "rig `{}` has no bundled measurements (the bundled data were measured on {}): give yours (columns speed_rpm,torque_nm,oil_temp_c), or use `tribo sweep` or `tribo run` for the model alone",
                rig.file.name,
                measured.join(", ")
            ),
        }
    })
}

/// Refuse speeds above the rig's declared top speed (`max_speed_rpm`), and data measured on
/// another rig than `rig` (the data file's `# rig:`) unless `any_rig` (`--data-for-any-rig`).
pub fn check_data_rig(rig: &Rig, data: &DataRun, any_rig: bool) -> Result<(), StudyError> {
    let err = |message: String| StudyError::Data {
        file: data.file.clone(),
        line: None,
        message,
    };
    if let Some(measured_on) = &data.meta.rig {
        let same = *measured_on == rig.file.name
            || rig.file.measured_as.as_deref() == Some(measured_on.as_str());
        if !any_rig && !same {
            return Err(err(format!(
                "these data were measured on rig `{measured_on}` (its `# rig:` line), and this study runs rig `{}`: scoring one engine against another's measurements says nothing about either; give data measured on `{}` with --data, or pass --data-for-any-rig if they do apply",
                rig.file.name, rig.file.name
            )));
        }
    }
    if let Some(top) = rig.file.max_speed_rpm {
        if let Some(row) = data.rows.iter().find(|r| r.speed_rpm > top) {
            return Err(err(format!(
                "{} rpm is above the top speed of rig `{}` (max_speed_rpm = {} rpm): no measurement can have been made there",
                readable(row.speed_rpm),
                rig.file.name,
                readable(top)
            )));
        }
    }
    Ok(())
}

/// Read a `speed_rpm,torque_nm,oil_temp_c` CSV from disk, or a bundled data file by name.
/// Lines starting with `#` are comments (sources, and the declarations of [`parse_meta`]).
pub fn read_data(arg: &str) -> Result<(PathBuf, Vec<DataRow>), StudyError> {
    let (path, text) = data_text(arg)?;
    parse_data(&path, &text).map(|r| (path, r))
}

/// A data file's name (`<bundled>/NAME` for a bundled one) and text: from disk, or bundled by
/// that name when no such file exists.
fn data_text(arg: &str) -> Result<(PathBuf, String), StudyError> {
    let path = PathBuf::from(arg);
    match tribo_config::files::read_text(&path) {
        Ok(t) => Ok((path, t)),
        Err(e) if !e.is_not_found() => Err(StudyError::Data {
            file: path,
            line: None,
            message: format!("the data file {e}"),
        }),
        Err(e) => match tribo_config::bundled::data(arg) {
            Some(t) => Ok((
                PathBuf::from(format!(
                    "<bundled>/{}",
                    tribo_config::bundled::file_name(arg)
                )),
                t.to_string(),
            )),
            None => Err(StudyError::Data {
                file: path,
                line: None,
                message: format!(
                    "{e}, and no bundled data file has that name; bundled: {}",
                    tribo_config::bundled::data_names().join(", ")
                ),
            }),
        },
    }
}

/// The largest measured torque accepted, N m: a motored engine's friction torque is tens of
/// N m at most, so a larger value is a unit or export error.
pub const MAX_DATA_TORQUE_NM: f64 = 1e4;
/// The highest measured speed accepted, rpm (no engine the rig models turns faster).
pub const MAX_DATA_SPEED_RPM: f64 = 30_000.0;
/// The lowest measured speed accepted, rpm: at least one revolution per second, or a plateau's
/// measurement window holds no whole revolution (the rig's window sets the final limit).
pub const MIN_DATA_SPEED_RPM: f64 = 60.0;

/// Check one data row's values against the physical limits; `cols` are the 0-based columns of
/// speed, torque and oil temperature. On error, says which column, what limit and why.
fn check_row(row: &DataRow, cols: (usize, usize, usize)) -> Result<(), String> {
    let (cs, ct, co) = cols;
    if !(MIN_DATA_SPEED_RPM..=MAX_DATA_SPEED_RPM).contains(&row.speed_rpm) {
        return Err(format!(
            "column `speed_rpm` (column {}): {} rpm is outside [{MIN_DATA_SPEED_RPM}, {MAX_DATA_SPEED_RPM}] rpm; a plateau needs at least one revolution per second to be measured, and no engine modelled turns faster than {MAX_DATA_SPEED_RPM} rpm",
            cs + 1,
            readable(row.speed_rpm)
        ));
    }
    if row.torque_nm.abs() > MAX_DATA_TORQUE_NM {
        return Err(format!(
            "column `torque_nm` (column {}): {} N m is beyond +-{MAX_DATA_TORQUE_NM} N m; a motored engine's friction torque is tens of N m at most, so check the units and the export",
            ct + 1,
            readable(row.torque_nm)
        ));
    }
    let (t_lo, t_hi) = tribo_core::oil::VALID_RANGE_C;
    if !(t_lo..=t_hi).contains(&row.oil_temp_c) {
        return Err(format!(
            "column `oil_temp_c` (column {}): {} C is outside the oil viscosity model's valid range [{t_lo}, {t_hi}] C",
            co + 1,
            readable(row.oil_temp_c)
        ));
    }
    Ok(())
}

/// Parse data text (see [`read_data`]).
pub fn parse_data(path: &Path, text: &str) -> Result<Vec<DataRow>, StudyError> {
    let err = |line: Option<u64>, message: String| StudyError::Data {
        file: path.to_path_buf(),
        line,
        message,
    };
    // A spreadsheet's byte order mark is not part of the first column's name.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
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
            let what = match cell.parse::<f64>() {
                Ok(x) if x.is_finite() => return Ok(x),
                // `1e400`, `inf`, `NaN`: numbers, but none a measurement can be.
                Ok(_) => "is not a finite number",
                Err(_) => "is not a number",
            };
            Err(err(
                line,
                format!("column `{name}` (column {}): `{cell}` {what}", i + 1),
            ))
        };
        let row = DataRow {
            speed_rpm: num(cs, "speed_rpm")?,
            torque_nm: num(ct, "torque_nm")?,
            oil_temp_c: num(co, "oil_temp_c")?,
        };
        check_row(&row, (cs, ct, co)).map_err(|m| err(line, m))?;
        rows.push(row);
    }
    if rows.is_empty() {
        return Err(err(None, "no data rows".into()));
    }
    rows.sort_by(|a, b| a.speed_rpm.total_cmp(&b.speed_rpm));
    if let Some(w) = rows.windows(2).find(|w| w[0].speed_rpm == w[1].speed_rpm) {
        return Err(err(
            None,
            format!(
                "two rows have the same speed ({} rpm); give each speed once",
                readable(w[0].speed_rpm)
            ),
        ));
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
        run_through(&mut r, rows)?;
    }
    Ok(r)
}

/// Drive `r` through the speeds of `rows` (the cycle of [`cycle_through`]) at their oil
/// temperatures, and validate it again.
fn run_through(r: &mut Rig, rows: &[DataRow]) -> Result<(), Box<RigError>> {
    r.file.cycle.segments = Some(cycle_through(rows));
    r.file.oil.temperature_c = Temperature::PerPlateau(rows.iter().map(|x| x.oil_temp_c).collect());
    r.overridden.push("cycle".into());
    r.overridden.push("oil.temperature_c".into());
    tribo_config::rig::revalidate(r).map_err(|mut e| {
        e.message.push_str(
            " (this run's cycle and oil temperatures are built from the data file's rows)",
        );
        e
    })
}

/// Run one rig, a single cylinder or an engine (steady-state or full cycle).
pub fn run_rig(rig: &Rig, registry: &LawRegistry, steady: bool) -> Result<RunResult, SimError> {
    let mut sim = tribo_config::rig::simulation(rig, registry)?;
    if steady {
        sim.run_steady()
    } else {
        sim.run()
    }
}

/// One law set's results against the data.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SetResult {
    /// Law-set name.
    pub lawset: String,
    /// On a rig with a drivetrain, per data point: whether the transducer stayed within its
    /// rating there (its oscillation width and limit torque); a point outside it was measured
    /// outside the instrument's rating.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instrument_ok: Option<Vec<bool>>,
    /// Its file.
    pub file: String,
    /// The run.
    pub run: RunResult,
    /// Model minus measurement at each speed, N m.
    pub errors_nm: Vec<f64>,
    /// Root-mean-square error, N m (in sample: the set's parameters as they are).
    pub rmse_nm: f64,
    /// Largest absolute error, N m.
    pub max_abs_error_nm: f64,
    /// Place in the ranking by cross-validated RMSE (1 = best); sets tied with each other
    /// ([`SetResult::tie`]) share the place of the first of them.
    pub rank: usize,
    /// The sets this one cannot be told apart from on these data, and why (`None`: none).
    #[serde(default)]
    pub tie: Option<Tie>,
    /// Joints this set leaves without a law although another set of the comparison gives them
    /// one ([`mark_uncovered_joints`]): its torque lacks their friction, so its ranking is not
    /// like for like. Empty when it covers every joint the others do.
    #[serde(default)]
    pub uncovered_joints: Vec<String>,
    /// Out-of-sample scores: leave-one-out RMSE, free parameters, AICc, BIC.
    pub scores: Scores,
    /// The linearised uncertainty of the free parameters and the 95% band of the torque.
    pub uncertainty: Uncertainty,
    /// How the set's free parameters were treated: fitted to these data before scoring, kept
    /// at the file's values (`--no-fit`), or none to fit; with each parameter's estimate.
    pub calibration: SetCalibration,
    /// The law set with the fitted values, as TOML (fitted sets only; `compare` writes it as
    /// `fitted_<set>.toml` beside the results).
    pub fitted_lawset_toml: Option<String>,
    /// Lower edge of the 95% confidence band of the model torque at each speed, N m: the
    /// delta-method band of `ln T` mapped back, `T exp(-h/T)` with `h` the linearised
    /// half-width, so it stays above zero (see [`crate::uncertainty::log_band`]).
    pub band_lower_nm: Option<Vec<f64>>,
    /// Upper edge of the band, `T exp(h/T)`, N m.
    pub band_upper_nm: Option<Vec<f64>>,
    /// Whether the band is wider than the spread of the measured torques (then the data do not
    /// determine this set's prediction); `None` when there is no band.
    pub band_wider_than_data: Option<bool>,
    /// Why there is no band, in words (`None` when there is one).
    pub band_note: Option<String>,
    /// How the torque moves as the oil warms, at each data point.
    pub temperature_response: TemperatureResponse,
    /// Scores on data never used in fitting (`--validate`).
    pub validation: Vec<Validation>,
}

/// Sets a comparison cannot tell apart: their ranking errors differ by less than the data's
/// noise ([`rank_sets`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tie {
    /// The other sets of the tie, in ranking order.
    pub with: Vec<String>,
    /// Whether every set of the tie gives the same torque at every data point (within
    /// [`SAME_TORQUE_NM`]): then they are one model as far as these data go.
    pub same_torques: bool,
    /// The largest difference between the tied sets' ranking errors, N m.
    pub error_spread_nm: f64,
    /// The tolerance the tie used: the data's noise, N m.
    pub noise_nm: f64,
}

/// Two sets whose torques differ by at most this at every data point give "the same torques",
/// N m: a fiftieth of the bundled data's declared noise, far below anything a torque
/// transducer resolves.
pub const SAME_TORQUE_NM: f64 = 1e-3;

/// How a set's free parameters entered a comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum CalibrationStatus {
    /// Calibrated on the comparison's data before it was scored (as `tribo fit` does).
    #[serde(rename = "fitted")]
    Fitted,
    /// Kept at the law-set file's values (`--no-fit`), and scored as they are.
    #[serde(rename = "not fitted")]
    NotFitted,
    /// The set has no free parameters.
    #[serde(rename = "no free parameters")]
    NoFreeParameters,
}

impl CalibrationStatus {
    /// The words used in tables, CSV and plot legends.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Fitted => "fitted",
            Self::NotFitted => "not fitted",
            Self::NoFreeParameters => "no free parameters",
        }
    }
}

/// One free parameter of a set in a comparison.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ParamEstimate {
    /// `joint.law.param`.
    pub id: String,
    /// The law-set file's value (the fit's own start point).
    pub start: f64,
    /// The value scored: fitted, or the file's when not fitted.
    pub value: f64,
    /// The allowed range.
    pub bounds: [f64; 2],
    /// `lower` or `upper` when the value sits on that bound.
    pub at_bound: Option<String>,
    /// 1-sigma uncertainty, where the data determine it.
    pub std_dev: Option<f64>,
    /// Fitted inside its range with a 1-sigma uncertainty at most half its value
    /// ([`crate::uncertainty::POORLY_DETERMINED`]).
    pub determined: bool,
}

/// How a set's free parameters were treated in a comparison, and their values.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SetCalibration {
    /// Fitted, not fitted, or nothing to fit.
    pub status: CalibrationStatus,
    /// Each free parameter.
    pub params: Vec<ParamEstimate>,
    /// Why the optimiser stopped (fitted sets).
    pub termination: Option<String>,
}

impl SetCalibration {
    /// Parameters on a bound.
    pub fn on_bounds(&self) -> usize {
        self.params.iter().filter(|p| p.at_bound.is_some()).count()
    }
    /// Parameters the data do not determine (on a bound, or without a usable sigma).
    pub fn undetermined(&self) -> usize {
        self.params.iter().filter(|p| !p.determined).count()
    }
}

/// How a study runs the rig at each speed. Serialized (and displayed) as `steady` or
/// `transient`, the words the JSON has always used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RunMode {
    /// The periodic steady state at each plateau speed, computed directly.
    Steady,
    /// The whole test cycle, ramps included, measured over each plateau's window.
    Transient,
}

impl RunMode {
    /// [`RunMode::Steady`] if `steady`, else [`RunMode::Transient`] (the `--steady` flag).
    pub fn from_steady(steady: bool) -> Self {
        if steady {
            Self::Steady
        } else {
            Self::Transient
        }
    }

    /// The word used in JSON, tables and plot titles.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Steady => "steady",
            Self::Transient => "transient",
        }
    }
}

impl std::fmt::Display for RunMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A side-by-side comparison.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Comparison {
    /// Rig name.
    pub rig: String,
    /// Data file.
    pub data_file: String,
    /// The measurements.
    pub data: Vec<DataRow>,
    /// Steady state at each speed, or the full test cycle (`"steady"` or `"transient"` in JSON).
    pub mode: RunMode,
    /// What the ranking rests on, in words.
    pub ranked_by: String,
    /// The data's noise, one standard deviation, N m, as the data file declares it.
    pub noise_nm: Option<f64>,
    /// What the scores let a user conclude, in one sentence ([`crate::verdict`]).
    pub verdict: crate::verdict::Verdict,
    /// Each law set, in the order given.
    pub sets: Vec<SetResult>,
    /// Law sets that gave no results (only when sets run in separate processes; in one
    /// process the first failure ends the study).
    #[serde(default)]
    pub failed: Vec<FailedSet>,
}

/// How `compare` scores the law sets.
#[derive(Debug, Clone)]
pub struct CompareOptions {
    /// Steady state at each speed instead of the full test cycle.
    pub steady: bool,
    /// Skip the leave-one-out refits (rank by in-sample RMSE, and say so).
    pub no_cv: bool,
    /// Score sets with free parameters at the file's values instead of fitting them first
    /// (each is then labelled "not fitted").
    pub no_fit: bool,
    /// Latin-hypercube start points of each set's calibration (besides its own values and the
    /// corners of its bounds).
    pub starts: usize,
    /// Data never used in fitting, scored separately.
    pub validate: Vec<DataRun>,
    /// Accept data whose `# rig:` names another rig (`--data-for-any-rig`).
    pub data_for_any_rig: bool,
    /// On a rig with a drivetrain, fit and score each set on the points its transducer
    /// measured within its rating only (`--trusted-points-only`); the others are still run
    /// and reported, marked by `instrument_ok`.
    pub trusted_points_only: bool,
}

impl Default for CompareOptions {
    fn default() -> Self {
        Self {
            steady: false,
            no_cv: false,
            no_fit: false,
            starts: crate::fit::DEFAULT_STARTS,
            validate: Vec::new(),
            data_for_any_rig: false,
            trusted_points_only: false,
        }
    }
}

/// The points of `data` the transducer measured within its rating with law set `ls` at the
/// file's values (a steady pre-run at the data's points); all of them on a rig without a
/// drivetrain or unless `options.trusted_points_only`.
fn trusted_rows(
    rig: &Rig,
    ls: &LawSet,
    data: &DataRun,
    registry: &LawRegistry,
    options: &CompareOptions,
) -> Result<DataRun, StudyError> {
    if !options.trusted_points_only || rig.file.drivetrain.is_none() {
        return Ok(data.clone());
    }
    let r = prepare(rig, ls, Some(&data.rows))?;
    let run = run_rig(&r, registry, true).map_err(|e| StudyError::Run {
        lawset: ls.name().into(),
        error: Box::new(e),
    })?;
    let ok = instrument_ok(&run).unwrap_or_default();
    let rows: Vec<DataRow> = data
        .rows
        .iter()
        .zip(&ok)
        .filter(|(_, ok)| **ok)
        .map(|(row, _)| *row)
        .collect();
    if rows.len() < 2 {
        return Err(StudyError::Data {
            file: data.file.clone(),
            line: None,
            message: format!(
                "--trusted-points-only: law set `{}` leaves {} of {} points within the transducer's rating, too few to fit or score",
                ls.name(),
                rows.len(),
                data.rows.len()
            ),
        });
    }
    Ok(DataRun {
        rows,
        ..data.clone()
    })
}

/// RMSE and largest absolute error of `model` against `measured`.
pub fn errors(model: &[f64], measured: &[f64]) -> (Vec<f64>, f64, f64) {
    let e: Vec<f64> = model.iter().zip(measured).map(|(m, d)| m - d).collect();
    let rmse = (e.iter().map(|x| x * x).sum::<f64>() / e.len().max(1) as f64).sqrt();
    let max = e.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
    (e, rmse, max)
}

/// One law set fitted to `data` (when it has free parameters and fitting is on), run against
/// it and scored: in-sample errors, out-of-sample scores, its band, its temperature response
/// and any validation data, all with the values it is ranked by.
fn score_set(
    rig: &Rig,
    ls: &LawSet,
    free: &[FreeParam],
    data: &DataRun,
    registry: &LawRegistry,
    options: &CompareOptions,
    spread: f64,
) -> Result<SetResult, StudyError> {
    let all = data;
    let trusted = trusted_rows(rig, ls, data, registry, options)?;
    let data = &trusted;
    let measured: Vec<f64> = all.rows.iter().map(|r| r.torque_nm).collect();
    let fitted = if free.is_empty() || options.no_fit {
        None
    } else {
        let fit_options = crate::fit::FitOptions {
            starts: options.starts,
            cross_validate: !options.no_cv,
            validate: Vec::new(),
            // The comparison has checked the data's rig already.
            data_for_any_rig: true,
        };
        Some(crate::fit::fit(
            rig,
            ls,
            free,
            std::slice::from_ref(data),
            registry,
            &fit_options,
        )?)
    };
    let used = fitted.as_ref().map_or(ls, |(_, l)| l);
    let r = prepare(rig, used, Some(&all.rows))?;
    let run = run_rig(&r, registry, options.steady).map_err(|e| StudyError::Run {
        lawset: ls.name().into(),
        error: Box::new(e),
    })?;
    let model: Vec<f64> = run
        .plateaus
        .iter()
        .map(|p| p.measured_torque_nm())
        .collect();
    let (errors_nm, mut rmse_nm, max_abs_error_nm) = errors(&model, &measured);
    let instrument_ok = instrument_ok(&run);
    // The points scored: the trusted ones under `--trusted-points-only`, else all.
    let subset = data.rows.len() < all.rows.len();
    let kept: Vec<f64> = if subset {
        errors_nm
            .iter()
            .zip(instrument_ok.iter().flatten())
            .filter(|(_, ok)| **ok)
            .map(|(e, _)| *e)
            .collect()
    } else {
        errors_nm.clone()
    };
    if subset {
        rmse_nm = (kept.iter().map(|x| x * x).sum::<f64>() / kept.len().max(1) as f64).sqrt();
    }
    let (mut scores, mut unc, calibration) = match &fitted {
        Some((f, _)) => (
            f.scores.clone(),
            f.uncertainty.clone(),
            fitted_calibration(f, free),
        ),
        None => {
            // Nothing fitted: scored as it is, like a set without free parameters.
            let tm = TorqueModel::new(rig, used, &[], vec![data.clone()], registry);
            let mut scores = score::scores_for_fit(&tm, &[], &kept, !options.no_cv);
            let status = if free.is_empty() {
                CalibrationStatus::NoFreeParameters
            } else {
                scores.notes.push(format!(
                    "not fitted (--no-fit): its {} free parameter{} keep the law-set file's values and it is scored as they are",
                    free.len(),
                    if free.len() == 1 { "" } else { "s" }
                ));
                CalibrationStatus::NotFitted
            };
            let calibration = SetCalibration {
                status,
                params: free
                    .iter()
                    .map(|f| ParamEstimate {
                        id: f.id.clone(),
                        start: f.value,
                        value: f.value,
                        bounds: f.bounds,
                        at_bound: crate::fit::bound_hit(f.value, f.bounds),
                        std_dev: None,
                        determined: false,
                    })
                    .collect(),
                termination: None,
            };
            (scores, Uncertainty::none(errors_nm.len()), calibration)
        }
    };
    // The in-sample figure is the compare run's own (steady or full cycle).
    scores.rmse_nm = rmse_nm;
    let prior = ls.prior_fit_on(&data.file);
    if let Some(prior) = prior {
        score::apply_prior_fit(&mut scores, &kept, prior);
        // Tuned elsewhere: no covariance of those numbers exists here.
        unc.band_half_width_nm = None;
    }
    if subset {
        // The fit's band covers the trusted points only, not every point the run reports.
        unc.band_half_width_nm = None;
    }
    let band = unc
        .band_half_width_nm
        .as_ref()
        .and_then(|h| crate::uncertainty::log_band(&model, h));
    let band_note = band
        .is_none()
        .then(|| band_missing(&calibration, prior, &unc, &model, data));
    let band_wider_than_data = band.as_ref().map(|(lo, hi)| {
        let widest = lo.iter().zip(hi).map(|(l, h)| h - l).fold(0.0, f64::max);
        widest > spread
    });
    let (band_lower_nm, band_upper_nm) = band.unzip();
    let validation = options
        .validate
        .iter()
        .map(|v| score::validate(rig, used, v, registry, options.steady))
        .collect::<Result<Vec<_>, _>>()?;
    let temperature_response = score::temperature_response(rig, used, data, registry)?;
    if temperature_response.max_rise_percent_per_10c > score::TEMPERATURE_RISE_FLAG_PERCENT {
        let (i, _) = temperature_response
            .percent_per_10c
            .iter()
            .enumerate()
            .fold(
                (0, f64::NEG_INFINITY),
                |a, (i, v)| if *v > a.1 { (i, *v) } else { a },
            );
        scores.notes.push(format!(
            "its torque rises {:.0}% per 10 C of oil warming at {:.0} rpm: full-film friction falls as oil thins and a mixed regime losing film rarely gives more than {:.0}%; check the law's regime transition before trusting this set away from the measured temperatures",
            temperature_response.max_rise_percent_per_10c,
            data.rows[i].speed_rpm,
            score::TEMPERATURE_RISE_FLAG_PERCENT
        ));
    }
    let fitted_lawset_toml = match &fitted {
        Some((f, l)) => Some(
            l.to_toml(&format!(
                "Fitted by `tribo compare` on rig {} against {}: RMSE {:.4} N m in sample, {} N m leave-one-out.\nParameters fitted: {}",
                rig.file.name,
                data.file.display(),
                f.rmse_nm,
                f.scores
                    .cv_rmse_nm
                    .map_or("(not computed)".to_string(), |v| format!("{v:.4}")),
                f.params.join(", ")
            ))
            .map_err(|e| StudyError::Data {
                file: ls.path.clone(),
                line: None,
                message: format!("the fitted law set cannot be written as TOML: {e}"),
            })?,
        ),
        None => None,
    };
    Ok(SetResult {
        lawset: ls.name().into(),
        file: ls.path.display().to_string(),
        run,
        errors_nm,
        rmse_nm,
        max_abs_error_nm,
        rank: 0,
        tie: None,
        uncovered_joints: Vec::new(),
        scores,
        uncertainty: unc,
        calibration,
        fitted_lawset_toml,
        band_lower_nm,
        band_upper_nm,
        band_wider_than_data,
        band_note,
        temperature_response,
        validation,
        instrument_ok,
    })
}

/// Per plateau of `run`, whether the transducer stayed within its rating (`None` on a rig
/// without a drivetrain, whose measurement is not modelled).
fn instrument_ok(run: &RunResult) -> Option<Vec<bool>> {
    run.plateaus
        .iter()
        .map(|p| p.instrument.as_ref().map(|i| i.within_rating()))
        .collect()
}

/// A fitted set's parameters as a comparison reports them (`free`: as the file gives them).
fn fitted_calibration(f: &crate::fit::FitResult, free: &[FreeParam]) -> SetCalibration {
    let params = (0..f.params.len())
        .map(|k| {
            let std_dev = f.std_dev.get(k).copied().flatten();
            let value = f.values[k];
            let at_bound = f.at_bound.get(k).cloned().flatten();
            ParamEstimate {
                id: f.params[k].clone(),
                start: free.get(k).map_or(f64::NAN, |p| p.value),
                value,
                bounds: f.bounds[k],
                determined: at_bound.is_none()
                    && std_dev.is_some_and(|sd| {
                        sd <= crate::uncertainty::POORLY_DETERMINED * value.abs()
                    }),
                at_bound,
                std_dev,
            }
        })
        .collect();
    SetCalibration {
        status: CalibrationStatus::Fitted,
        params,
        termination: Some(f.termination.clone()),
    }
}

/// Why a set has no 95% band, in words.
fn band_missing(
    calibration: &SetCalibration,
    prior: Option<&tribo_config::lawset::PriorFit>,
    unc: &Uncertainty,
    model: &[f64],
    data: &DataRun,
) -> String {
    let k = calibration.params.len();
    if let Some(p) = prior {
        return format!(
            "its {} numbers tuned to these data elsewhere have no covariance Tribo could estimate",
            p.parameters
        );
    }
    match calibration.status {
        CalibrationStatus::NoFreeParameters => {
            return "no free parameters: nothing is estimated from these data, so its error is what its residuals show".into()
        }
        CalibrationStatus::NotFitted => {
            return "not fitted (--no-fit): no covariance without a fit".into()
        }
        CalibrationStatus::Fitted => {}
    }
    let on = calibration.on_bounds();
    if on == k {
        return format!(
            "{} on {} bound{}: held there, nothing inside its range is left to vary",
            if k == 1 {
                "its free parameter is".to_string()
            } else {
                format!("all {k} free parameters are")
            },
            if k == 1 { "its" } else { "their" },
            if k == 1 { "" } else { "s" }
        );
    }
    if let Some((i, t)) = model.iter().enumerate().find(|(_, t)| **t <= 0.0) {
        return format!(
            "the model torque is {t:.3} N m at {:.0} rpm: a band of a positive torque (log scale) does not exist there",
            data.rows.get(i).map_or(f64::NAN, |d| d.speed_rpm)
        );
    }
    if unc.dof == 0 {
        return "no residual degrees of freedom (as many parameters as points)".into();
    }
    "the data do not determine its parameters (see the statements below)".into()
}

/// Run every law set on `rig` at the data's speeds and temperatures, in parallel, and score
/// each out of sample. The order of the results is the order of `lawsets`, whatever the
/// scheduling; `rank` orders them by cross-validated RMSE.
///
/// The laws come from plugins, so this example is compiled but not run here; the
/// `compare_bundled` example of this crate runs it (`cargo run --release -p tribo-studies
/// --example compare_bundled` after `cargo build --release`).
///
/// ```no_run
/// use std::path::{Path, PathBuf};
/// use tribo_config::{bundled, lawset::LawSet, rig::load_rig};
/// use tribo_plugin_api::loader::discover;
/// use tribo_studies::study::{compare, CompareOptions, DataRun};
///
/// let rig = load_rig(Path::new(bundled::DEFAULT_RIG), &[])?;
/// let sets = [LawSet::load("fedem-baseline")?, LawSet::load("stribeck-duty")?];
/// let data = DataRun::read(bundled::DEFAULT_DATA)?;
/// // Law plugins from a directory, TRIBO_PLUGIN_PATH and the executable's directory.
/// let registry = discover(&[PathBuf::from("target/release")])?;
/// let options = CompareOptions { steady: true, ..CompareOptions::default() };
/// let cmp = compare(&rig, &sets, &data, &registry, &options)?;
/// for set in &cmp.sets {
///     println!("{:<16} rank {} RMSE {:.4} N m", set.lawset, set.rank, set.rmse_nm);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn compare(
    rig: &Rig,
    lawsets: &[LawSet],
    data: &DataRun,
    registry: &LawRegistry,
    options: &CompareOptions,
) -> Result<Comparison, StudyError> {
    // A drivetrain's chain is integrated in the steady state only (`sim::torsional`).
    let effective = CompareOptions {
        steady: options.steady || rig.file.drivetrain.is_some(),
        ..options.clone()
    };
    let options = &effective;
    // Every input checked before anything runs.
    check_lawsets(rig, lawsets, registry)?;
    for d in std::iter::once(data).chain(&options.validate) {
        check_data_rig(rig, d, options.data_for_any_rig)?;
        check_data(rig, d)?;
    }
    let measured: Vec<f64> = data.rows.iter().map(|r| r.torque_nm).collect();
    let spread = measured.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        - measured.iter().copied().fold(f64::INFINITY, f64::min);
    // Every set's free parameters are resolved before anything runs: a bad law-set entry is
    // reported at once, not after the other sets' runs.
    let frees = lawsets
        .iter()
        .map(|ls| {
            if ls.file.laws.iter().any(|e| !e.free.is_empty()) {
                ls.free_params(registry, None).map_err(Box::new)
            } else {
                Ok(Vec::new())
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    let sets = lawsets
        .par_iter()
        .zip(frees.par_iter())
        .map(|(ls, free)| score_set(rig, ls, free, data, registry, options, spread))
        .collect::<Result<Vec<_>, StudyError>>()?;
    let mut cmp = Comparison {
        rig: rig.file.name.clone(),
        data_file: data.file.display().to_string(),
        data: data.rows.clone(),
        mode: RunMode::from_steady(options.steady),
        ranked_by: ranked_by(options.no_cv).into(),
        noise_nm: data.meta.noise_nm,
        verdict: Default::default(),
        sets,
        failed: Vec::new(),
    };
    cmp.rank(options.no_cv);
    Ok(cmp)
}

impl Comparison {
    /// Rank the sets ([`rank_sets`]) and judge the result ([`crate::verdict::judge`]); again
    /// after sets run in separate processes are merged.
    pub fn rank(&mut self, no_cv: bool) {
        let noise = self.noise_nm.unwrap_or_else(|| {
            let n = self.data.len().max(1) as f64;
            crate::verdict::ASSUMED_NOISE_SHARE
                * self.data.iter().map(|d| d.torque_nm.abs()).sum::<f64>()
                / n
        });
        rank_sets(&mut self.sets, no_cv, noise);
        mark_uncovered_joints(&mut self.sets);
        self.verdict = crate::verdict::judge(self);
        if let Some(note) = self.instrument_note() {
            self.verdict.sentence.push_str(&note);
        }
    }

    /// The verdict's note on a rig with a drivetrain: the data points measured outside the
    /// transducer's rating by any set's run (`instrument_ok`), which no law can be judged on.
    fn instrument_note(&self) -> Option<String> {
        let outside: Vec<String> = self
            .data
            .iter()
            .enumerate()
            .filter(|(i, _)| {
                self.sets.iter().any(|s| {
                    s.instrument_ok
                        .as_ref()
                        .is_some_and(|ok| ok.get(*i) == Some(&false))
                })
            })
            .map(|(_, row)| format!("{:.0}", row.speed_rpm))
            .collect();
        if outside.is_empty() {
            return None;
        }
        Some(format!(
            "; the transducer worked outside its rating at {} of {} points ({} rpm: instrument_ok false), so those measurements are not trusted{}",
            outside.len(),
            self.data.len(),
            outside.join(", "),
            if self.sets.iter().all(|s| s.instrument_ok.is_none()) {
                ""
            } else {
                " (--trusted-points-only scores the rest)"
            }
        ))
    }
}

/// What the ranking of a comparison rests on, in words.
pub fn ranked_by(no_cv: bool) -> &'static str {
    if no_cv {
        "in-sample RMSE (cross-validation skipped with --no-cv): rewards sets with many free parameters"
    } else {
        "leave-one-out cross-validated RMSE: each point predicted by the set refitted without it (a set without free parameters: its in-sample RMSE; sets tuned to these data elsewhere have no out-of-sample figure and rank last)"
    }
}

/// Give each set its `rank`: cross-validated sets first, by their out-of-sample error; sets
/// without one (tuned elsewhere, or a fold failed) after them, by their in-sample error. With
/// `no_cv`, all by in-sample error. Used again when sets run in separate processes are merged.
///
/// Sets of one class whose errors lie within `noise_nm` (the data's one-sigma noise) of the
/// first set of their group are **tied**: these data cannot tell them apart, so they share a
/// place and each records the others ([`SetResult::tie`]). A difference smaller than the noise
/// of a single measurement is no evidence for one law over another.
pub fn rank_sets(sets: &mut [SetResult], no_cv: bool, noise_nm: f64) {
    let key = |s: &SetResult| {
        if no_cv {
            (0, s.rmse_nm)
        } else {
            match s.scores.cv_rmse_nm {
                Some(cv) => (0, cv),
                None => (1, s.rmse_nm),
            }
        }
    };
    let mut order: Vec<usize> = (0..sets.len()).collect();
    order.sort_by(|a, b| {
        let (ka, kb) = (key(&sets[*a]), key(&sets[*b]));
        ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
    });
    for (place, &i) in order.iter().enumerate() {
        sets[i].rank = place + 1;
        sets[i].tie = None;
    }
    // Groups of tied sets, each led by its best set.
    let mut start = 0;
    while start < order.len() {
        let lead = key(&sets[order[start]]);
        let mut end = start + 1;
        while end < order.len() {
            let k = key(&sets[order[end]]);
            // A NaN error ties with nothing.
            let within = (k.1 - lead.1)
                .partial_cmp(&noise_nm)
                .is_some_and(|o| o.is_le());
            if k.0 != lead.0 || !within {
                break;
            }
            end += 1;
        }
        let group = &order[start..end];
        if group.len() > 1 {
            let same_torques = group.iter().all(|&i| {
                sets[i]
                    .errors_nm
                    .iter()
                    .zip(&sets[group[0]].errors_nm)
                    .all(|(a, b)| (a - b).abs() <= SAME_TORQUE_NM)
            });
            let spread = key(&sets[group[group.len() - 1]]).1 - lead.1;
            let place = sets[group[0]].rank;
            for &i in group {
                sets[i].rank = place;
                sets[i].tie = Some(Tie {
                    with: group
                        .iter()
                        .filter(|&&j| j != i)
                        .map(|&j| sets[j].lawset.clone())
                        .collect(),
                    same_torques,
                    error_spread_nm: spread,
                    noise_nm,
                });
            }
        }
        start = end;
    }
}

/// Set each set's [`SetResult::uncovered_joints`]: the joints some other set puts a law on
/// (in its first plateau's per-law results) and this one does not, in the order they first
/// appear.
pub fn mark_uncovered_joints(sets: &mut [SetResult]) {
    let covered = |s: &SetResult| -> Vec<String> {
        let mut joints: Vec<String> = Vec::new();
        for j in s.run.plateaus.first().map_or(&[][..], |p| &p.joints[..]) {
            if !joints.contains(&j.joint) {
                joints.push(j.joint.clone());
            }
        }
        joints
    };
    let each: Vec<Vec<String>> = sets.iter().map(covered).collect();
    let mut all: Vec<&String> = Vec::new();
    for j in each.iter().flatten() {
        if !all.contains(&j) {
            all.push(j);
        }
    }
    for (s, own) in sets.iter_mut().zip(&each) {
        s.uncovered_joints = all
            .iter()
            .filter(|j| !own.contains(j))
            .map(|j| (*j).clone())
            .collect();
    }
}

/// A law set that gave no results (its worker process crashed, hung, ran out of memory, or its
/// run failed), reported beside the sets that did.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FailedSet {
    /// Law-set name.
    pub lawset: String,
    /// Why, in words (names the law, its library and the signal or limit).
    pub message: String,
}

/// Which body a mass study scales.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
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
    tribo_config::rig::revalidate(&r)?;
    Ok(r)
}

/// One joint's and law's response to the scaling at one speed.
#[derive(Debug, Clone, Serialize, Deserialize)]
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
#[derive(Debug, Clone, Serialize, Deserialize)]
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
    /// The FEDEM thesis's change for the same speed (table 10.6 minus 10.5, rod at 0.6), N m:
    /// present only in the rows of the thesis's own law set (see [`is_thesis_lawset`]) at
    /// scale 0.6 of the rod; absent (null) for every other law set.
    pub fedem_change_nm: Option<f64>,
    /// Per joint and law.
    pub joints: Vec<JointChange>,
}

/// One law set's mass response.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MassResponse {
    /// Law set.
    pub lawset: String,
    /// Body scaled.
    pub body: ScaledBody,
    /// Per scale and speed.
    pub changes: Vec<SpeedChange>,
}

/// Torque change per speed and joint when `body` is scaled by each of `scales`, for each law
/// set, against the unscaled rig. Runs in parallel; results in input order. `fedem` (speed,
/// change) is attached only to the thesis's own law set ([`is_thesis_lawset`]).
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
    // Every input checked before anything runs.
    check_lawsets(rig, lawsets, registry)?;
    check_scales(rig, body, scales)?;
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
        // FEDEM's change belongs to the thesis's model only, never to a user's law set.
        let fedem = fedem.filter(|_| is_thesis_lawset(ls));
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

/// The name of the thesis's own law set, whose FEDEM results (tables 10.5, 10.6) may be shown
/// beside it.
pub const THESIS_LAWSET: &str = "fedem-baseline";

/// Whether `lawset` is the thesis's FEDEM model: the same laws, joints and parameters as the
/// bundled `fedem-baseline` (compared as parsed values, so comments, formatting, the file's
/// name and the set's name do not matter, while any changed coefficient or added law does).
/// Only then do the FEDEM thesis's numbers belong beside its results.
pub fn is_thesis_lawset(lawset: &LawSet) -> bool {
    tribo_config::bundled::lawset(THESIS_LAWSET)
        .and_then(|text| LawSet::from_text(Path::new(THESIS_LAWSET), text).ok())
        .is_some_and(|thesis| thesis.file.laws == lawset.file.laws)
}

/// FEDEM's torque change with the rod at 60% per speed: table 10.6 minus table 10.5.
pub fn fedem_rod_change() -> Vec<(f64, f64)> {
    // The FEDEM tables have `speed_rpm,sim_speed_rad_s,torque_nm` (no oil temperature), so they
    // are read by column name here rather than through `parse_data`.
    let read = |name: &str| -> Vec<(f64, f64)> {
        let Some(text) = tribo_config::bundled::data(name) else {
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

/// What the oil of a sweep is: the rig's descriptive fields and its viscosity model, so the
/// JSON says which curve produced the viscosities.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct OilInfo {
    /// Name, if the rig gives one.
    pub name: Option<String>,
    /// SAE viscosity grade, if given.
    pub grade: Option<String>,
    /// Source of the viscosity data, if given.
    pub source: Option<String>,
    /// The viscosity model and its constants.
    pub viscosity: tribo_core::oil::ViscosityModel,
    /// Density, kg/m^3.
    pub density_kg_m3: f64,
    /// One-line description (name, grade, model constants, source), as printed.
    pub description: String,
}

impl OilInfo {
    /// The oil of `rig`.
    pub fn of(rig: &Rig) -> Self {
        let o = &rig.file.oil;
        Self {
            name: o.name.clone(),
            grade: o.grade.clone(),
            source: o.source.clone(),
            viscosity: o.viscosity.clone(),
            density_kg_m3: o.density_kg_m3,
            description: o.describe(),
        }
    }

    /// Dynamic viscosity at `t_c` C, Pa s (kinematic viscosity times density, as the solver
    /// computes it).
    pub fn dynamic_pa_s(&self, t_c: f64) -> f64 {
        self.viscosity.kinematic_cst(t_c) * 1e-6 * self.density_kg_m3
    }
}

/// Friction torque of one joint (all its laws summed) at one sweep point.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct JointTorque {
    /// Joint name.
    pub joint: String,
    /// Friction torque at the crank, N m.
    pub friction_torque_nm: f64,
}

/// One (speed, temperature) point of a law set's sweep.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SweepPoint {
    /// Engine speed, rpm.
    pub speed_rpm: f64,
    /// Oil temperature, C.
    pub oil_temp_c: f64,
    /// Dynamic viscosity at that temperature, Pa s.
    pub viscosity_pa_s: f64,
    /// Mean motoring torque over the steady revolution, N m.
    pub torque_nm: f64,
    /// Per joint of the rig, in its report order (`RigFile::joint_names`: the single-cylinder
    /// rig's five, or an engine's mains and cylinder joints); joints without a law give zero.
    pub joints: Vec<JointTorque>,
    /// The Sandoval-Heywood correlation at this point (`tribo_core::correlation`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub correlation: Option<tribo_core::correlation::Correlation>,
}

/// One law set's sweep: points ordered by temperature, then speed (the input order).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SweepSet {
    /// Law-set name.
    pub lawset: String,
    /// Its file.
    pub file: String,
    /// Every (temperature, speed) point.
    pub points: Vec<SweepPoint>,
    /// Warnings of the runs.
    pub warnings: Vec<String>,
}

impl SweepSet {
    /// The torque at speed index `i` and temperature index `k` of a sweep over `n_speeds`
    /// speeds.
    pub fn torque(&self, k: usize, i: usize, n_speeds: usize) -> f64 {
        self.points
            .get(k * n_speeds + i)
            .map_or(f64::NAN, |p| p.torque_nm)
    }
}

/// A temperature and speed sweep of several law sets (steady state at every point).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Sweep {
    /// Rig name.
    pub rig: String,
    /// The oil (name, grade, model, source).
    pub oil: OilInfo,
    /// Always [`RunMode::Steady`]: each point is the periodic steady state at that speed.
    pub mode: RunMode,
    /// Oil temperatures, C, in the order given.
    pub temps_c: Vec<f64>,
    /// Dynamic viscosity at each temperature, Pa s.
    pub viscosities_pa_s: Vec<f64>,
    /// Engine speeds, rpm, in the order given.
    pub speeds_rpm: Vec<f64>,
    /// Each law set.
    pub sets: Vec<SweepSet>,
    /// How FMEP is defined on this rig (basis, displacement), for the correlation's tables.
    #[serde(default)]
    pub fmep: tribo_core::sim::Fmep,
    /// Law sets that gave no results (only when sets run in separate processes).
    #[serde(default)]
    pub failed: Vec<FailedSet>,
}

/// Why a sweep's temperatures or speeds are unusable; names the command-line option.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{option}: {message}")]
pub struct SweepInputError {
    /// The option, e.g. `--temps`.
    pub option: String,
    /// What is wrong and what is allowed.
    pub message: String,
}

/// Parse a comma-separated list of numbers given to `option` (`40,50,60`). Empty lists, empty
/// items and non-numbers are errors naming the option.
pub fn parse_list(option: &str, text: &str) -> Result<Vec<f64>, SweepInputError> {
    let err = |message: String| SweepInputError {
        option: option.into(),
        message,
    };
    if text.trim().is_empty() {
        return Err(err(
            "the list is empty; give comma-separated numbers, e.g. 40,60,80".into(),
        ));
    }
    text.split(',')
        .map(|item| {
            let item = item.trim();
            item.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| err(format!("`{item}` is not a number")))
        })
        .collect()
}

/// Check a sweep's temperatures (inside [`tribo_core::oil::VALID_RANGE_C`]) and speeds (positive),
/// both non-empty and without repeats, before any run starts.
pub fn check_sweep_inputs(temps_c: &[f64], speeds_rpm: &[f64]) -> Result<(), SweepInputError> {
    let err = |option: &str, message: String| SweepInputError {
        option: option.into(),
        message,
    };
    let (lo, hi) = tribo_core::oil::VALID_RANGE_C;
    if temps_c.is_empty() {
        return Err(err("--temps", "the list is empty".into()));
    }
    if speeds_rpm.is_empty() {
        return Err(err("--speeds", "the list is empty".into()));
    }
    if let Some(t) = temps_c.iter().find(|t| !(**t >= lo && **t <= hi)) {
        return Err(err(
            "--temps",
            format!(
                "{} C is outside the viscosity model's valid range [{lo}, {hi}] C",
                readable(*t)
            ),
        ));
    }
    if let Some(s) = speeds_rpm.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
        return Err(err(
            "--speeds",
            format!("every speed must be positive (rpm), got {}", readable(*s)),
        ));
    }
    for (option, list, unit) in [("--temps", temps_c, "C"), ("--speeds", speeds_rpm, "rpm")] {
        for (i, a) in list.iter().enumerate() {
            if list[..i].contains(a) {
                return Err(err(option, format!("{a} {unit} is given twice")));
            }
        }
    }
    Ok(())
}

/// The speeds of the plateaus of `rig`'s own test cycle, rpm, in the order held (each once).
pub fn plateau_speeds(rig: &Rig) -> Vec<f64> {
    let mut speed = 0.0;
    let mut out: Vec<f64> = Vec::new();
    for s in rig.file.cycle.segments() {
        match s {
            Segment::Ramp { to_rpm, .. } => speed = to_rpm,
            Segment::Hold { .. } => {
                if !out.contains(&speed) {
                    out.push(speed);
                }
            }
        }
    }
    out
}

/// Refuse `speeds_rpm` (given by `option`) above the rig's declared top speed
/// (`max_speed_rpm`), naming both.
pub fn check_speeds_for_rig(
    rig: &Rig,
    speeds_rpm: &[f64],
    option: &str,
) -> Result<(), SweepInputError> {
    match (
        rig.file.max_speed_rpm,
        speeds_rpm
            .iter()
            .find(|s| rig.file.max_speed_rpm.is_some_and(|top| **s > top)),
    ) {
        (Some(top), Some(s)) => Err(SweepInputError {
            option: option.into(),
            message: format!(
                "{} rpm is above the top speed of rig `{}` (max_speed_rpm = {} rpm)",
                readable(*s),
                rig.file.name,
                readable(top)
            ),
        }),
        _ => Ok(()),
    }
}

/// `rig` with `lawset` attached, driven through `speeds_rpm` (the thesis's ramp-and-hold
/// pattern) with the oil at `temp_c` on every plateau.
fn sweep_rig(
    rig: &Rig,
    lawset: &LawSet,
    speeds_rpm: &[f64],
    temp_c: f64,
) -> Result<Rig, Box<RigError>> {
    let rows: Vec<DataRow> = speeds_rpm
        .iter()
        .map(|s| DataRow {
            speed_rpm: *s,
            torque_nm: 0.0,
            oil_temp_c: temp_c,
        })
        .collect();
    prepare(rig, lawset, Some(&rows))
}

/// Check a sweep's temperatures and speeds, and that the rig can be driven through them (with
/// the first of `lawsets` attached): an error names `--speeds` or `--temps`, never a `--set`
/// nobody gave. No plugin is needed, so a caller can check before it starts any worker.
pub fn check_sweep(
    rig: &Rig,
    lawsets: &[LawSet],
    temps_c: &[f64],
    speeds_rpm: &[f64],
) -> Result<(), StudyError> {
    check_sweep_inputs(temps_c, speeds_rpm)?;
    if let Some(ls) = lawsets.first() {
        for t in temps_c {
            sweep_rig(rig, ls, speeds_rpm, *t).map_err(|mut e| {
                let speeds = e.field.starts_with("cycle");
                e.file = PathBuf::from(if speeds { "--speeds" } else { "--temps" });
                if let Some(i) = e.message.find(" (this run's cycle") {
                    e.message.truncate(i);
                }
                e.message.push_str(if speeds {
                    " (the sweep drives the rig through the speeds of --speeds)"
                } else {
                    " (the sweep holds the oil at each temperature of --temps)"
                });
                e
            })?;
        }
    }
    Ok(())
}

/// Check that the rig's `body` can be scaled by every factor of `scales` (a mass-response
/// study): an error names `--scale`. No plugin is needed.
pub fn check_scales(rig: &Rig, body: ScaledBody, scales: &[f64]) -> Result<(), StudyError> {
    for s in scales {
        scaled(rig, body, *s).map_err(|mut e| {
            e.file = PathBuf::from("--scale");
            e.message
                .push_str(&format!(" (the rig's value times the scale factor {s})"));
            e
        })?;
    }
    Ok(())
}

/// Run every law set at every temperature over `speeds_rpm`, in steady state, in parallel
/// (one job per law set and temperature; `progress`, if given, counts finished jobs). Results
/// are in input order whatever the scheduling, so the output is deterministic.
pub fn sweep(
    rig: &Rig,
    lawsets: &[LawSet],
    temps_c: &[f64],
    speeds_rpm: &[f64],
    registry: &LawRegistry,
    progress: Option<&tribo_core::observe::Position>,
) -> Result<Sweep, StudyError> {
    // Every input checked before anything runs.
    check_speeds_for_rig(rig, speeds_rpm, "--speeds")?;
    check_sweep(rig, lawsets, temps_c, speeds_rpm)?;
    check_lawsets(rig, lawsets, registry)?;
    let jobs: Vec<(usize, f64)> = (0..lawsets.len())
        .flat_map(|i| temps_c.iter().map(move |t| (i, *t)))
        .collect();
    let runs = jobs
        .par_iter()
        .map(|(i, t)| {
            let ls = &lawsets[*i];
            let r = sweep_rig(rig, ls, speeds_rpm, *t)?;
            let run = run_rig(&r, registry, true).map_err(|e| StudyError::Run {
                lawset: ls.name().into(),
                error: Box::new(e),
            });
            if let Some(p) = progress {
                p.inc();
            }
            run
        })
        .collect::<Result<Vec<RunResult>, StudyError>>()?;
    let oil = OilInfo::of(rig);
    let joint_names = rig.model().joint_names();
    let mut sets = Vec::with_capacity(lawsets.len());
    for (i, ls) in lawsets.iter().enumerate() {
        let mut points = Vec::with_capacity(temps_c.len() * speeds_rpm.len());
        // Each warning once, with the temperatures it was given at.
        let mut by_warning: Vec<(&String, Vec<f64>)> = Vec::new();
        for (k, t) in temps_c.iter().enumerate() {
            let run = &runs[i * temps_c.len() + k];
            for w in &run.warnings {
                match by_warning.iter_mut().find(|(x, _)| *x == w) {
                    Some((_, ts)) => ts.push(*t),
                    None => by_warning.push((w, vec![*t])),
                }
            }
            for p in &run.plateaus {
                let joints = joint_names
                    .iter()
                    .map(|name| JointTorque {
                        joint: name.clone(),
                        // Folded from +0: a joint without a law has no friction, 0, where
                        // an empty float `sum` gives -0 (written "-0" in the CSV).
                        friction_torque_nm: p
                            .joints
                            .iter()
                            .filter(|j| j.joint == *name)
                            .fold(0.0, |sum, j| sum + j.friction_torque_nm),
                    })
                    .collect();
                points.push(SweepPoint {
                    speed_rpm: p.set_speed_rpm,
                    oil_temp_c: p.oil_temp_c,
                    viscosity_pa_s: p.viscosity_pa_s,
                    torque_nm: p.motoring_torque_nm,
                    joints,
                    correlation: p.correlation.clone(),
                });
            }
        }
        let warnings = by_warning
            .into_iter()
            .map(|(w, ts)| {
                let list: Vec<String> = ts.iter().map(|t| t.to_string()).collect();
                if ts.len() == temps_c.len() && ts.len() > 1 {
                    format!("at every oil temperature ({} C): {w}", list.join(", "))
                } else {
                    format!("{} C: {w}", list.join(", "))
                }
            })
            .collect();
        sets.push(SweepSet {
            lawset: ls.name().into(),
            file: ls.path.display().to_string(),
            points,
            warnings,
        });
    }
    Ok(Sweep {
        rig: rig.file.name.clone(),
        viscosities_pa_s: temps_c.iter().map(|t| oil.dynamic_pa_s(*t)).collect(),
        oil,
        mode: RunMode::Steady,
        temps_c: temps_c.to_vec(),
        speeds_rpm: speeds_rpm.to_vec(),
        fmep: runs.first().map(|r| r.fmep).unwrap_or_default(),
        sets,
        failed: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::RunMode;

    #[test]
    fn run_mode_serializes_to_the_words_the_json_always_had() {
        for (mode, word) in [
            (RunMode::Steady, "steady"),
            (RunMode::Transient, "transient"),
        ] {
            let json = serde_json::to_string(&mode).expect("serializes");
            assert_eq!(json, format!("\"{word}\""));
            assert_eq!(mode.to_string(), word);
        }
        assert_eq!(RunMode::from_steady(true), RunMode::Steady);
        assert_eq!(RunMode::from_steady(false), RunMode::Transient);
    }
}
