//! Law sets: files that attach laws and parameters to joints, usable with any rig, and that
//! mark parameters as free (with bounds) for calibration.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use tribo_core::sim::readable;
use tribo_plugin_api::loader::LawRegistry;
use tribo_plugin_api::ParamValue;

use crate::files::read_text;
use crate::rig::{
    expand_joint, file_error, line_col, LawArg, LawOrigin, LawRef, Rig, RigError, RigFile, Source,
    JOINT_KINDS, JOINT_NAMES,
};

/// A law-set file as written.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LawSetFile {
    /// Name shown in comparisons.
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Laws, each on one joint.
    pub laws: Vec<LawEntry>,
    /// Parameters tuned to measured data outside Tribo (by hand, or in another program), which
    /// Tribo cannot refit: scores on those data count them and give no out-of-sample error.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior_fit: Option<PriorFit>,
}

/// A record that a law set's values were tuned to a data set elsewhere.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PriorFit {
    /// How many numbers were tuned.
    pub parameters: usize,
    /// The data file they were tuned to (file name, as bundled or on disk).
    pub data: String,
    /// Where the tuning is described.
    #[serde(default)]
    pub source: String,
}

/// One law on one joint.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LawEntry {
    /// Joint name.
    pub joint: String,
    /// Law name.
    pub law: String,
    /// Parameters (law defaults for the rest).
    #[serde(default)]
    pub params: toml::Table,
    /// Parameters free for calibration, with `[lower, upper]` bounds.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub free: BTreeMap<String, [f64; 2]>,
}

/// A loaded law set.
#[derive(Debug, Clone)]
pub struct LawSet {
    /// Content.
    pub file: LawSetFile,
    /// Where it came from.
    pub path: PathBuf,
    /// The file's path and text, for locating errors.
    source: Arc<Source>,
    /// Where each entry of `file.laws` came from when not from the file: the `--law`
    /// arguments added by [`LawSet::add_law_args`] (`None`: an entry of the file).
    arg_origins: Vec<Option<LawOrigin>>,
}

/// Whether `name` can name joints of some rig: a single-cylinder joint, an engine joint
/// (`main_2`, `piston_3`: numbered from 1) or a group (`main_*`, `piston_*`).
pub fn is_joint_pattern(name: &str) -> bool {
    if JOINT_NAMES.contains(&name) {
        return true;
    }
    JOINT_KINDS.iter().any(|k| {
        name.strip_prefix(k)
            .and_then(|rest| rest.strip_prefix('_'))
            .is_some_and(|n| n == "*" || n.parse::<usize>().is_ok_and(|n| n >= 1))
    })
}

/// A calibration parameter: `JOINT.LAW.PARAM`.
#[derive(Debug, Clone, PartialEq)]
pub struct FreeParam {
    /// `joint.law.param`.
    pub id: String,
    /// Index of the law entry.
    pub entry: usize,
    /// Parameter name.
    pub param: String,
    /// Bounds.
    pub bounds: [f64; 2],
    /// Current value.
    pub value: f64,
}

fn error(path: &Path, text: &str, field: &str, message: String) -> RigError {
    RigError::at(path, text, field, message)
}

/// The longest law-set name allowed.
pub const MAX_NAME_LEN: usize = 64;

/// Check a law-set name: 1 to [`MAX_NAME_LEN`] characters of ASCII letters, digits, `-`, `_`
/// and `.`, not starting with `.`. Names become file names (plots, fitted sets), so nothing
/// else (no path separators, no `..`, no commas or spaces) is allowed. On error, says what is
/// wrong.
///
/// ```
/// use tribo_config::lawset::check_name;
/// assert!(check_name("stribeck-duty_2.1").is_ok());
/// assert!(check_name("x/../../pwned").is_err());
/// assert!(check_name(".hidden").is_err());
/// assert!(check_name("").is_err());
/// ```
pub fn check_name(name: &str) -> Result<(), String> {
    if name.is_empty() {
        return Err("is empty".into());
    }
    if name.len() > MAX_NAME_LEN {
        return Err(format!("is {} characters long", name.len()));
    }
    if name.starts_with('.') {
        return Err("starts with `.`".into());
    }
    if let Some(c) = name
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.')))
    {
        return Err(format!("contains `{}`", c.escape_default()));
    }
    Ok(())
}

/// A parameter asked to be fitted: law entry index, parameter name, bounds from the file.
type WantedParam = (usize, String, Option<[f64; 2]>);

impl LawSet {
    /// Load a law set from a file, or a bundled one by name (`fedem-baseline`), and check it:
    /// joints that exist, free parameters with valid bounds. Errors carry file, line and column.
    ///
    /// ```
    /// use std::path::Path;
    /// use tribo_config::lawset::LawSet;
    /// use tribo_config::rig::load_rig;
    ///
    /// let set = LawSet::load("stribeck-duty")?;
    /// assert_eq!(set.name(), "stribeck-duty");
    ///
    /// // Applied to a rig, the set replaces the laws the rig lists on every joint.
    /// let mut rig = load_rig(Path::new("crf250r-motored"), &[])?;
    /// set.apply(&mut rig);
    /// let piston: Vec<&str> = rig.file.joints.piston.laws.iter().map(|l| l.law.as_str()).collect();
    /// assert_eq!(piston, ["stribeck-duty"]);
    ///
    /// // Neither a file nor a bundled name.
    /// assert!(LawSet::load("no-such-set").is_err());
    /// # Ok::<(), tribo_config::rig::RigError>(())
    /// ```
    pub fn load(arg: &str) -> Result<Self, RigError> {
        let path = PathBuf::from(arg);
        let (path, text) = match read_text(&path) {
            Ok(t) => (path, t),
            Err(e) if !e.is_not_found() => return Err(file_error(&path, "law-set file", &e)),
            Err(e) => match crate::bundled::lawset(arg) {
                Some(t) => (
                    PathBuf::from(format!("<bundled>/{}.toml", arg.trim_end_matches(".toml"))),
                    t.to_string(),
                ),
                None => {
                    return Err(RigError {
                        file: path,
                        line: None,
                        column: None,
                        field: "(file)".into(),
                        message: format!(
                            "{e}, and no bundled law set has that name; bundled: {}",
                            crate::bundled::lawset_names().join(", ")
                        ),
                    })
                }
            },
        };
        Self::from_text(&path, &text)
    }

    /// Parse a law set from text.
    pub fn from_text(path: &Path, text: &str) -> Result<Self, RigError> {
        let file: LawSetFile = toml::from_str(text).map_err(|e| {
            let at = e.span().map(|s| line_col(text, s.start));
            RigError {
                file: path.to_path_buf(),
                line: at.map(|a| a.0),
                column: at.map(|a| a.1),
                field: "(law set)".into(),
                message: e.message().to_string(),
            }
        })?;
        if let Err(why) = check_name(&file.name) {
            return Err(error(
                path,
                text,
                "name",
                format!(
                    "law-set name `{}` {why}; a name is used as a file name, so it must be 1 to {MAX_NAME_LEN} characters of ASCII letters, digits, `-`, `_` and `.`, not starting with `.`",
                    file.name.escape_default()
                ),
            ));
        }
        let set = Self {
            file,
            path: path.to_path_buf(),
            source: Arc::new(Source {
                path: path.to_path_buf(),
                text: text.to_string(),
            }),
            arg_origins: Vec::new(),
        };
        for (i, e) in set.file.laws.iter().enumerate() {
            if !is_joint_pattern(&e.joint) {
                return Err(error(
                    path,
                    text,
                    &format!("laws[{i}].joint"),
                    format!(
                        "the rig has no joint `{}`; joints are {} on the single-cylinder rig, main_1 .. main_n and per cylinder k big_end_k, small_end_k, piston_k on an engine, or a group: main_*, big_end_*, small_end_*, piston_*",
                        e.joint,
                        JOINT_NAMES.join(", ")
                    ),
                ));
            }
            for (p, [lo, hi]) in &e.free {
                if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                    return Err(error(
                        path,
                        text,
                        &format!("laws[{i}].free.{p}"),
                        format!("bounds must be finite with lower < upper, got [{lo}, {hi}]"),
                    ));
                }
            }
        }
        Ok(set)
    }

    /// Add `--law JOINT=LAW[:PARAMS.toml]` arguments to the set (a user's law beside the set's).
    pub fn add_law_args(&mut self, args: &[String]) -> Result<(), RigError> {
        for arg in args {
            let LawArg { joint, law, origin } = crate::rig::parse_law_arg(arg)?;
            self.arg_origins.resize(self.file.laws.len(), None);
            self.arg_origins.push(Some(origin));
            self.file.laws.push(LawEntry {
                joint,
                law: law.law,
                params: law.params,
                free: BTreeMap::new(),
            });
        }
        Ok(())
    }

    /// Parameters tuned to `data_file` outside Tribo, if the set records such a tuning for a
    /// file of that name.
    pub fn prior_fit_on(&self, data_file: &Path) -> Option<&PriorFit> {
        let name = data_file.file_name()?.to_string_lossy();
        self.file
            .prior_fit
            .as_ref()
            .filter(|p| crate::bundled::file_name(&p.data) == name)
    }

    /// Name.
    pub fn name(&self) -> &str {
        &self.file.name
    }

    /// Replace every law of `rig` with this set's laws. Each law remembers its entry (or
    /// `--law` argument), so an error about it is reported there ([`Rig::error`]).
    ///
    /// An entry's `joint` may be a group (`main_*`, `piston_*`, ...) or, on an engine, a
    /// single-cylinder name meaning every cylinder's joint (`docs/engines.md`); each joint it
    /// names gets the law. An entry naming no joint of this rig (`piston_5` on a twin,
    /// `main_a` on an engine) is recorded in [`Rig::unattached`] and refused when the rig's
    /// laws are checked or bound.
    pub fn apply(&self, rig: &mut Rig) {
        for name in JOINT_NAMES {
            if let Some(j) = rig.file.joints.get_mut(name) {
                j.laws.clear();
            }
        }
        if let Some(e) = rig.file.engine.as_mut() {
            e.laws.clear();
        }
        rig.law_origins.clear();
        rig.unattached.clear();
        for (i, e) in self.file.laws.iter().enumerate() {
            let origin = self
                .arg_origins
                .get(i)
                .cloned()
                .flatten()
                .unwrap_or_else(|| LawOrigin::LawSet {
                    file: self.source.clone(),
                    entry: i,
                });
            let law = LawRef {
                law: e.law.clone(),
                params: e.params.clone(),
            };
            let joints = expand_joint(&e.joint, &rig.file);
            if joints.is_empty() {
                rig.unattached.push(self.unattached(i, &e.joint, &rig.file));
            }
            for name in joints {
                let laws = match rig.file.engine.as_mut() {
                    Some(engine) => engine.laws.entry(name.clone()).or_default(),
                    None => match rig.file.joints.get_mut(&name) {
                        Some(j) => &mut j.laws,
                        None => continue,
                    },
                };
                rig.law_origins
                    .insert((name.clone(), laws.len()), origin.clone());
                laws.push(law.clone());
            }
        }
    }

    /// The error for entry `i`, whose `joint` names no joint of the rig `file`.
    fn unattached(&self, i: usize, joint: &str, file: &RigFile) -> RigError {
        let joints = match &file.engine {
            Some(e) => e.joint_names().join(", "),
            None => JOINT_NAMES.join(", "),
        };
        let why = match &file.engine {
            Some(_) if joint.starts_with("main_") && !joint.ends_with('*') => {
                " (an engine's mains are main_1 .. main_n; main_* attaches a law to each)"
            }
            _ => "",
        };
        self.error(
            &format!("laws[{i}].joint"),
            format!(
                "the rig `{}` has no joint `{joint}`{why}; its joints are {joints}, and the groups main_*, big_end_*, small_end_*, piston_*",
                file.name
            ),
        )
    }

    /// Free parameters: those marked in the file, or `ids` (`joint.law.param`) with bounds from
    /// the file or, failing that, the law's declared range. Start values from the file or the
    /// law's default.
    pub fn free_params(
        &self,
        registry: &LawRegistry,
        ids: Option<&[String]>,
    ) -> Result<Vec<FreeParam>, RigError> {
        let out = self
            .wanted_params(ids)?
            .into_iter()
            .map(|(i, param, bounds)| self.free_param(registry, i, param, bounds))
            .collect::<Result<Vec<_>, _>>()?;
        if out.is_empty() {
            return Err(self.error(
                "laws",
                "no free parameters: mark some with `free = { PARAM = [lo, hi] }` or pass --params"
                    .into(),
            ));
        }
        Ok(out)
    }

    /// Check every entry's parameters against its law's declaration (names, types, ranges)
    /// without a rig and without running any law code: what a run would refuse, reported now,
    /// located in the law set's text (`laws[i].params.NAME`).
    pub fn check_params(&self, registry: &LawRegistry) -> Result<(), RigError> {
        for (i, e) in self.file.laws.iter().enumerate() {
            let lib = registry
                .get(&e.law)
                .map_err(|err| self.error(&format!("laws[{i}].law"), err.to_string()))?;
            tribo_plugin_api::describe::check_params(lib.description(), &e.params).map_err(
                |err| {
                    let field = if err.parameter.is_empty() {
                        format!("laws[{i}].params")
                    } else {
                        format!("laws[{i}].params.{}", err.parameter)
                    };
                    self.error(&field, format!("law `{}`: {}", e.law, err.message))
                },
            )?;
        }
        Ok(())
    }

    /// An error about `field` of this law set, located in its text.
    fn error(&self, field: &str, message: String) -> RigError {
        error(&self.source.path, &self.source.text, field, message)
    }

    /// The parameters asked for, as (law entry, parameter, bounds from the file): those marked
    /// `free` in the file, or `ids` (`joint.law.param`).
    fn wanted_params(&self, ids: Option<&[String]>) -> Result<Vec<WantedParam>, RigError> {
        let Some(ids) = ids else {
            let mut wanted = Vec::new();
            for (i, e) in self.file.laws.iter().enumerate() {
                for (p, b) in &e.free {
                    wanted.push((i, p.clone(), Some(*b)));
                }
            }
            return Ok(wanted);
        };
        let mut wanted = Vec::new();
        for id in ids {
            let parts: Vec<&str> = id.splitn(3, '.').collect();
            let [joint, law, param] = parts[..] else {
                return Err(self.error("laws", format!("`{id}` is not JOINT.LAW.PARAM")));
            };
            let i = self
                .file
                .laws
                .iter()
                .position(|e| e.joint == joint && e.law == law)
                .ok_or_else(|| {
                    self.error(
                        "laws",
                        format!("`{id}`: the law set has no law `{law}` on joint `{joint}`"),
                    )
                })?;
            wanted.push((
                i,
                param.to_string(),
                self.file.laws[i].free.get(param).copied(),
            ));
        }
        Ok(wanted)
    }

    /// Parameter `param` of law entry `i` as a free parameter: its declaration from the loaded
    /// law (which must have it, as a number), bounds from the file or the declared range, the
    /// start value from the file or the default, clamped into the bounds.
    fn free_param(
        &self,
        registry: &LawRegistry,
        i: usize,
        param: String,
        bounds: Option<[f64; 2]>,
    ) -> Result<FreeParam, RigError> {
        let e = &self.file.laws[i];
        let id = format!("{}.{}.{}", e.joint, e.law, param);
        let lib = registry
            .get(&e.law)
            .map_err(|err| self.error(&format!("laws[{i}].law"), err.to_string()))?;
        let spec = lib
            .description()
            .parameters
            .iter()
            .find(|p| p.name == param)
            .ok_or_else(|| {
                self.error(
                    &format!("laws[{i}].free"),
                    format!("law `{}` has no parameter `{param}`", e.law),
                )
            })?;
        let ParamValue::Number(default) = spec.default else {
            return Err(self.error(
                &format!("laws[{i}].free"),
                format!("`{id}` is not a number and cannot be fitted"),
            ));
        };
        let value = e
            .params
            .get(&param)
            .and_then(|v| v.as_float().or(v.as_integer().map(|x| x as f64)))
            .unwrap_or(default);
        if let Some([lo, hi]) = bounds {
            // The fit would otherwise try values the law refuses (and fail part-way), or stop
            // at a bound that is not the law's.
            if lo < spec.min || hi > spec.max {
                return Err(self.error(
                    &format!("laws[{i}].free.{param}"),
                    format!(
                        "the bounds [{}, {}] of free parameter `{id}` reach outside the range law `{}` accepts for `{param}`, {}; give bounds inside it",
                        readable(lo),
                        readable(hi),
                        e.law,
                        spec.range_text()
                    ),
                ));
            }
        }
        let bounds = bounds.unwrap_or([spec.min, spec.max]);
        Ok(FreeParam {
            id,
            entry: i,
            param,
            bounds,
            value: value.clamp(bounds[0], bounds[1]),
        })
    }

    /// A copy with the free parameters set to `values`.
    pub fn with_values(&self, free: &[FreeParam], values: &[f64]) -> Self {
        let mut s = self.clone();
        for (f, v) in free.iter().zip(values) {
            s.file.laws[f.entry]
                .params
                .insert(f.param.clone(), toml::Value::Float(*v));
        }
        s
    }

    /// The law set as TOML text, with a header comment.
    pub fn to_toml(&self, header: &str) -> Result<String, toml::ser::Error> {
        let body = toml::to_string(&self.file)?;
        let comments: String = header.lines().map(|l| format!("# {l}\n")).collect();
        Ok(format!("{comments}\n{body}"))
    }
}
