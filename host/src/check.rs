//! `tribo check-law` and `tribo plot-law`: a law taken by library path or by name, its
//! parameters from a TOML file, the conformance checks of
//! [`tribo_plugin_api::conformance`] run on it, and its force-velocity curves sampled for a
//! plot ([`crate::plots::write_law_plot`]).
//!
//! The command runs these in a worker process (`isolate`): a law that crashes it, hangs, exits
//! or kills its process group fails the check with a message naming the law and the signal or
//! limit. With `--in-process` they run in the `tribo` process, whose guards name the law
//! (`isolate::guard`) as it ends with exit status 1 or the signal's.

use std::ops::Deref;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use tribo_plugin_api::loader::{LawError, LawLibrary, LawRegistry};
use tribo_plugin_api::{JointKind, LawInput};

/// What can go wrong before a law is checked or plotted.
#[derive(Debug, thiserror::Error)]
pub enum CheckError {
    /// The parameter file could not be read.
    #[error("cannot read the parameter file `{path}`: {source}")]
    ReadParams {
        /// File.
        path: PathBuf,
        /// OS error.
        source: std::io::Error,
    },
    /// The parameter file is not a TOML table (the message carries line and column).
    #[error("the parameter file `{path}` is not valid TOML: {message}")]
    ParseParams {
        /// File.
        path: PathBuf,
        /// The TOML parser's message, with line and column.
        message: String,
    },
    /// The law could not be found, loaded or created.
    #[error(transparent)]
    Law(#[from] LawError),
    /// The bundled rig whose geometry and oil the plot uses could not be loaded.
    #[error("loading the bundled rig for the plot: {0}")]
    Rig(String),
    /// A joint name `plot-law --joint` does not know.
    #[error("unknown joint `{0}`; expected one of main_a, main_b, big_end, small_end, piston")]
    UnknownJoint(String),
    /// The law failed while being sampled for the plot.
    #[error("law `{law}` failed at {input}: {message}")]
    Sample {
        /// Law name.
        law: String,
        /// The input, in words.
        input: String,
        /// The law's error.
        message: String,
    },
}

/// A law library: one the registry holds, or one loaded from a path given on the command line.
pub enum LawRef<'a> {
    /// Found by name through the registry.
    Registered(&'a LawLibrary),
    /// Loaded from a file path.
    Loaded(Box<LawLibrary>),
}

impl Deref for LawRef<'_> {
    type Target = LawLibrary;
    fn deref(&self) -> &LawLibrary {
        match self {
            LawRef::Registered(l) => l,
            LawRef::Loaded(l) => l,
        }
    }
}

/// Whether `spec` names a file rather than a law: it has a directory part or a shared-library
/// extension, or an existing file has that name.
fn is_path(spec: &str) -> bool {
    let p = Path::new(spec);
    spec.contains(std::path::MAIN_SEPARATOR)
        || spec.contains('/')
        || matches!(
            p.extension().and_then(|e| e.to_str()),
            Some("so" | "dylib" | "dll")
        )
        || p.is_file()
}

/// The law `spec` names: a library file (loaded now) or a law name looked up in `registry`.
pub fn open_law<'a>(registry: &'a LawRegistry, spec: &str) -> Result<LawRef<'a>, CheckError> {
    if is_path(spec) {
        Ok(LawRef::Loaded(Box::new(LawLibrary::load(Path::new(spec))?)))
    } else {
        Ok(LawRef::Registered(registry.get(spec)?))
    }
}

/// The parameter table in `path` (`--params`), or an empty table (defaults) without one.
pub fn read_params(path: Option<&Path>) -> Result<toml::Table, CheckError> {
    let Some(path) = path else {
        return Ok(toml::Table::new());
    };
    let text = std::fs::read_to_string(path).map_err(|source| CheckError::ReadParams {
        path: path.to_path_buf(),
        source,
    })?;
    text.parse::<toml::Table>()
        .map_err(|e| CheckError::ParseParams {
            path: path.to_path_buf(),
            message: e.to_string().trim_end().to_string(),
        })
}

/// One force-velocity curve: a load and an oil temperature.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Curve {
    /// Normal load, N.
    pub load_n: f64,
    /// Oil temperature, C.
    pub oil_temp_c: f64,
    /// Dynamic viscosity at that temperature, Pa s.
    pub viscosity_pa_s: f64,
    /// (sliding velocity m/s, force N or torque N m), velocity ascending through zero.
    pub points: Vec<(f64, f64)>,
    /// (sliding speed m/s, |force|) on a logarithmic speed grid, for the low-speed detail.
    pub speed_points: Vec<(f64, f64)>,
}

/// A law's force-velocity curves at the loads and oil temperatures of `plot-law`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LawCurves {
    /// Law name.
    pub law: String,
    /// Joint the curves are for (a joint of the bundled rig).
    pub joint: String,
    /// Its kind.
    pub kind: JointKind,
    /// Contact radius, m.
    pub radius_m: f64,
    /// Whether the law is stateful (then each point is the force in steady sliding).
    pub stateful: bool,
    /// One curve per load and temperature.
    pub curves: Vec<Curve>,
}

/// Loads of the plot, N: light, moderate and heavy for a piston skirt or a bearing of the
/// bundled engine.
pub const PLOT_LOADS_N: [f64; 3] = [200.0, 1000.0, 5000.0];
/// Oil temperatures of the plot, C: a cold engine and a hot one.
pub const PLOT_TEMPS_C: [f64; 2] = [40.0, 100.0];
/// The largest sliding speed plotted, m/s (a main bearing or piston of the bundled engine at
/// 9000 rpm reaches about 20 m/s).
pub const PLOT_MAX_SPEED: f64 = 20.0;

/// Sample `lib` (with `params`) on joint `joint` of the bundled rig `crf250r-motored`: force
/// (prismatic) or torque (revolute) against the sliding velocity at the contact, at
/// [`PLOT_LOADS_N`] and [`PLOT_TEMPS_C`] with the rig oil's viscosity. On a revolute joint the
/// engine speed is the joint's speed (a main bearing); on the piston it is the speed whose mean
/// piston speed is the sliding speed. A stateful law is first slid at each velocity until it
/// has covered 1 mm or 0.5 s, whichever is longer, so each point is steady sliding.
pub fn sample_law(
    lib: &LawLibrary,
    params: &toml::Table,
    joint: &str,
) -> Result<LawCurves, CheckError> {
    let rig = crate::rig::load_rig(Path::new("crf250r-motored"), &[])
        .map_err(|e| CheckError::Rig(e.to_string()))?;
    let model = &rig.file;
    let geometry = model
        .joints
        .named()
        .into_iter()
        .find(|(name, _)| *name == joint)
        .map(|(_, j)| (j.radius_m, j.length_m))
        .ok_or_else(|| CheckError::UnknownJoint(joint.to_string()))?;
    let kind = if joint == "piston" {
        JointKind::Prismatic
    } else {
        JointKind::Revolute
    };
    let crank_radius = model.geometry.crank_radius_m;
    let inst = lib.create(params)?;
    let stateful = inst.state_size() > 0;
    let linear: Vec<f64> = (0..=200)
        .map(|k| PLOT_MAX_SPEED * (k as f64 - 100.0) / 100.0)
        .collect();
    let logs: Vec<f64> = (0..=120)
        .map(|k| 1e-5 * (PLOT_MAX_SPEED / 1e-5).powf(k as f64 / 120.0))
        .collect();
    let mut curves = Vec::new();
    for &t in &PLOT_TEMPS_C {
        let eta = model.oil.viscosity.kinematic_cst(t) * 1e-6 * model.oil.density_kg_m3;
        for &load in &PLOT_LOADS_N {
            let at = |vs: f64| -> Result<f64, CheckError> {
                let mut input = LawInput::at_rest(kind);
                input.contact_radius_m = geometry.0;
                input.contact_length_m = geometry.1;
                input.normal_load_n = load;
                match kind {
                    JointKind::Revolute => input.reaction_x_n = load,
                    JointKind::Prismatic => input.reaction_y_n = load,
                }
                input.oil_temp_c = t;
                input.viscosity_pa_s = eta;
                let rel = match kind {
                    JointKind::Revolute => vs / geometry.0,
                    JointKind::Prismatic => vs,
                };
                input.engine_speed_rad_s = match kind {
                    JointKind::Revolute => rel.abs(),
                    // Mean piston speed 2 r w / pi equal to the sliding speed.
                    JointKind::Prismatic => std::f64::consts::PI * vs.abs() / (2.0 * crank_radius),
                };
                let mut input = input.with_velocity(rel);
                let failed = |e: LawError, input: &LawInput| CheckError::Sample {
                    law: lib.name().to_string(),
                    input: tribo_plugin_api::conformance::describe_input(input),
                    message: e.to_string(),
                };
                let mut state = inst.new_state()?;
                if stateful {
                    const STEPS: usize = 5000;
                    let time = (1e-3 / vs.abs().max(1e-12)).clamp(0.5, 1e3);
                    input.dt_s = time / STEPS as f64;
                    for _ in 0..STEPS {
                        inst.commit(&input, &mut state)
                            .map_err(|e| failed(e, &input))?;
                    }
                }
                Ok(inst
                    .evaluate(&input, &state)
                    .map_err(|e| failed(e, &input))?
                    .force)
            };
            let points = linear
                .iter()
                .map(|&v| at(v).map(|f| (v, f)))
                .collect::<Result<Vec<_>, _>>()?;
            let speed_points = logs
                .iter()
                .map(|&v| at(v).map(|f| (v, f.abs())))
                .collect::<Result<Vec<_>, _>>()?;
            curves.push(Curve {
                load_n: load,
                oil_temp_c: t,
                viscosity_pa_s: eta,
                points,
                speed_points,
            });
        }
    }
    Ok(LawCurves {
        law: lib.name().to_string(),
        joint: joint.to_string(),
        kind,
        radius_m: geometry.0,
        stateful,
        curves,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_and_names_are_told_apart() {
        assert!(is_path("target/release/libtribo_law_coulomb.so"));
        assert!(is_path("libtribo_law_coulomb.so"));
        assert!(is_path("./x"));
        assert!(!is_path("coulomb"));
        assert!(!is_path("stribeck-duty"));
    }

    #[test]
    fn a_bad_parameter_file_names_file_line_and_column() {
        let dir = tempfile::tempdir().expect("temp dir");
        let f = dir.path().join("p.toml");
        std::fs::write(&f, "mu = 0.1\nmu_s = = 2\n").expect("write");
        let e = read_params(Some(&f)).expect_err("not TOML").to_string();
        assert!(e.contains("p.toml") && e.contains("line 2"), "{e}");
        let e = read_params(Some(&dir.path().join("missing.toml")))
            .expect_err("missing")
            .to_string();
        assert!(e.contains("missing.toml"), "{e}");
    }
}
