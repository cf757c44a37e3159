//! A study's inputs: measured data files (their metadata, checks and the rig's bundled data),
//! law sets checked against the rig and each other, the rig prepared for a data run's cycle,
//! and one run of it.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use tribo_config::lawset::LawSet;
use tribo_config::rig::{readable, Rig, RigError, Temperature};
use tribo_core::cycle::Segment;
use tribo_core::sim::{RunResult, SimError};
use tribo_plugin_api::loader::LawRegistry;

use crate::error::StudyError;

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

/// RMSE and largest absolute error of `model` against `measured`.
pub fn errors(model: &[f64], measured: &[f64]) -> (Vec<f64>, f64, f64) {
    let e: Vec<f64> = model.iter().zip(measured).map(|(m, d)| m - d).collect();
    let rmse = (e.iter().map(|x| x * x).sum::<f64>() / e.len().max(1) as f64).sqrt();
    let max = e.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
    (e, rmse, max)
}
