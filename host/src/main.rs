//! The `tribo` command: a thin layer over the host library that parses arguments, runs one
//! command and reports errors with their context.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, Parser, Subcommand};
use serde::{Deserialize, Serialize};
use tribo::isolate::{self, guard, Event, WorkerFailure};
use tribo::progress::Progress;
use tribo::{laws, scaffold};
use tribo_plugin_api::loader::{discover, LawRegistry};

/// Tribo: a virtual engine-friction test bench with friction and damping laws as plugins.
#[derive(Parser)]
#[command(version, about, long_about = None, max_term_width = 100)]
struct Cli {
    /// Extra plugin library or directory (searched before TRIBO_PLUGIN_PATH and the tribo
    /// executable's directory); may be repeated.
    #[arg(long = "plugin", global = true, value_name = "PATH")]
    plugins: Vec<PathBuf>,

    /// No progress display on standard error (it only appears on a terminal anyway).
    #[arg(long, global = true)]
    quiet: bool,

    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List every law found: name, version, ABI, file, summary and parameters.
    Laws(LawsArgs),
    /// Run a rig through its test cycle and report plateau torques, per-joint friction and the
    /// energy balance.
    Run(RunArgs),
    /// Run law sets side by side on a rig against measured torque: table, CSV, JSON, SVG plots.
    Compare(CompareArgs),
    /// How the motoring torque and each joint's friction change when a body is made lighter or
    /// heavier (the thesis's lighter-rod study), per law set.
    MassResponse(MassResponseArgs),
    /// The drivetrain's natural frequencies and mode shapes (linearised, at crank speed) and
    /// its Campbell diagram (`--svg`), for a rig with a `[drivetrain]` or an elastic
    /// crankshaft (`[engine.crankshaft]`).
    Modes(ModesArgs),
    /// Calibrate a law set's free parameters to measured torque (least squares, steady state).
    Fit(FitArgs),
    /// Motoring torque over oil temperature and engine speed for each law set (steady state):
    /// a table per law set, sweep.csv, sweep.json and one plot per law set.
    Sweep(SweepArgs),
    /// Generate a new law plugin crate with a documented law, parameters and unit tests.
    NewLaw(NewLawArgs),
    /// Check a law library against the contract (description, parameter ranges, finite and
    /// dissipative output over a sweep, dF/dv, pure evaluate, commit, threads); exit 1 naming
    /// the failed checks.
    CheckLaw(CheckLawArgs),
    /// Plot a law's force (or torque) against sliding velocity at three loads and two oil
    /// temperatures (SVG).
    PlotLaw(PlotLawArgs),
    /// Internal: serve the jobs of a parent `tribo` (they arrive on the channel it set up).
    #[command(name = "__worker", hide = true)]
    Worker,
    /// Export a rig with its laws as an FMI 2.0 Co-Simulation FMU (docs/fmu.md).
    #[command(subcommand)]
    Fmu(FmuCommand),
    /// Internal: serve one FMU instance (the FMU's worker process).
    #[command(name = "__fmu-worker", hide = true)]
    FmuWorker(FmuWorkerArgs),
}

/// The `tribo fmu` subcommands.
#[derive(Subcommand)]
enum FmuCommand {
    /// Write an FMU (FMI 2.0 Co-Simulation, Linux x86_64) of a rig with its laws: the law
    /// libraries and the solver travel inside it, nothing else is needed where it is imported.
    Export(FmuExportArgs),
}

/// The arguments of `tribo fmu export`.
#[derive(Args)]
struct FmuExportArgs {
    #[command(flatten)]
    rig: RigArgs,
    /// The FMU's drive input: `crank-speed` (rad/s; the crank turns at it, the drive torque
    /// it takes is an output) or `drive-torque` (N.m; the crank accelerates under it against
    /// friction from the `crank_speed_start` parameter, its speed is an output).
    #[arg(long, default_value = "crank-speed", value_parser = ["crank-speed", "drive-torque"])]
    input: String,
    /// The FMU file to write.
    #[arg(long, value_name = "FILE.fmu")]
    out: PathBuf,
}

/// The arguments of the hidden FMU worker subcommand.
#[derive(Args)]
struct FmuWorkerArgs {
    /// The FMU's resources directory.
    resources: PathBuf,
}

/// How a command treats its law plugins: in worker processes (the default: one per law set of
/// a study, one for a run or a law check), with limits, or in this process.
#[derive(Args, Clone, Serialize, Deserialize)]
struct IsolationArgs {
    /// Run the laws in this process instead of worker processes: a few milliseconds faster to
    /// start, and a debugger sees the law; but a law that crashes, exits or kills its process
    /// group then takes tribo (and for a kill, the shell or script that started it) down with it.
    #[arg(long)]
    in_process: bool,
    /// Wall-time limit of each worker process (of this process with --in-process), s (0: none).
    #[arg(long, default_value_t = isolate::DEFAULT_TIME_LIMIT_S, value_name = "S", value_parser = limit_seconds, allow_negative_numbers = true)]
    time_limit_s: f64,
    /// Resident-memory limit of each worker process (of this process with --in-process), MiB
    /// (0: none).
    #[arg(long, default_value_t = isolate::DEFAULT_MEMORY_LIMIT_MB, value_name = "MIB", value_parser = clap::value_parser!(u64).range(0..=isolate::MAX_MEMORY_MB))]
    memory_limit_mb: u64,
    /// Longest time one law call may take, s (0: none): a law stuck inside one call fails its
    /// run or law set, naming the law, its joint and the call's inputs.
    #[arg(long, default_value_t = isolate::DEFAULT_CALL_LIMIT_S, value_name = "S", value_parser = limit_seconds, allow_negative_numbers = true)]
    call_limit_s: f64,
}

/// A number of seconds for a limit option, bounded where it is parsed (a limit of 1e300 s
/// would overflow every clock).
fn limit_seconds(text: &str) -> Result<f64, String> {
    let s: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a number of seconds"))?;
    isolate::seconds("", s).map_err(|e| e.message)
}

impl IsolationArgs {
    /// The limits.
    fn limits(&self) -> anyhow::Result<isolate::Limits> {
        Ok(isolate::Limits {
            time_s: self.time_limit_s,
            memory_mb: self.memory_limit_mb,
            call_s: self.call_limit_s,
        }
        .checked(["--time-limit-s", "--memory-limit-mb", "--call-limit-s"])?)
    }
}

/// The arguments of `tribo laws`.
#[derive(Args)]
struct LawsArgs {
    /// Machine-readable JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// A rig with its laws, as `run` and `fmu export` take it.
#[derive(Args)]
struct RigArgs {
    /// Rig file (TOML) or bundled rig name.
    rig: PathBuf,
    /// Attach a law to a joint: JOINT=LAW or JOINT=LAW:PARAMS.toml. The first --law for a
    /// joint replaces the laws the rig lists there; further ones add to it.
    #[arg(long = "law", value_name = "JOINT=LAW[:PARAMS_TOML_FILE]")]
    laws: Vec<String>,
    /// Override any rig value by its dotted path, e.g. bodies.rod.mass_scale=0.6.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Another oil: a TOML file with an [oil] table (name, grade, source, viscosity,
    /// density_kg_m3), applied before --set.
    #[arg(long, value_name = "FILE.toml")]
    oil: Option<PathBuf>,
    /// Attach a law set (bundled name or file), replacing the rig's laws; --law adds to it.
    #[arg(long)]
    lawset: Option<String>,
}

impl RigArgs {
    /// The rig: the file (or bundled rig) with the oil file and `--set`s, then the law set,
    /// then `--law`s.
    fn load(&self) -> anyhow::Result<tribo::rig::Rig> {
        let sets = with_oil_file(self.oil.as_deref(), self.sets.clone())?;
        rig_with_laws(&self.rig, &sets, self.lawset.as_deref(), &self.laws)
    }
}

/// A rig with its `--set`s (the oil file already among them), then the law set, then the
/// `--law`s: what `run` (in its worker) and `fmu export` load.
fn rig_with_laws(
    rig: &std::path::Path,
    sets: &[String],
    lawset: Option<&str>,
    laws: &[String],
) -> anyhow::Result<tribo::rig::Rig> {
    let mut rig = tribo::rig::load_rig(rig, sets)?;
    if let Some(ls) = lawset {
        tribo::lawset::LawSet::load(ls)?.apply(&mut rig);
    }
    tribo::rig::attach_laws(&mut rig, laws)?;
    Ok(rig)
}

/// The arguments of `tribo run`.
#[derive(Args)]
struct RunArgs {
    #[command(flatten)]
    rig: RigArgs,
    /// Compute each plateau's periodic steady state directly instead of the whole cycle.
    #[arg(long)]
    steady: bool,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Also write plateaus.csv and joints.csv into this directory.
    #[arg(long, value_name = "DIR")]
    csv: Option<PathBuf>,
    /// Stream the time history (one line per step) to this CSV file (not with --steady, which
    /// computes each plateau directly and has no time history).
    #[arg(long, value_name = "FILE", conflicts_with = "steady")]
    timeseries: Option<PathBuf>,
    /// Also write crank-angle-resolved results into this directory: per plateau, one cycle at
    /// the plateau speed (CSV of friction torque, power, normal load, sliding speed and regime
    /// per joint and law; bearing loads and pressures; friction-vs-angle and polar load plots;
    /// on an engine also each cylinder's big-end load, side thrust and pressures, and each
    /// main bearing's load).
    #[arg(long = "crank-angle", value_name = "DIR")]
    crank_angle: Option<PathBuf>,
    /// Also write the FMEP breakdown (fmep.csv; fmep.svg, one line per component and the total) into this directory.
    #[arg(long, value_name = "DIR")]
    fmep: Option<PathBuf>,
    /// Angular resolution of --crank-angle, degrees, from 0.01 to 10 (at most 72 000 samples
    /// per cycle).
    #[arg(long = "resolution-deg", default_value_t = 0.5, value_name = "DEG", value_parser = resolution_deg, allow_negative_numbers = true)]
    resolution_deg: f64,
    /// Refuse to run a rig with no law on any joint (which gives a frictionless mechanism's
    /// torque, zero on average; without this flag it is a warning).
    #[arg(long)]
    require_laws: bool,
    /// Drive the crank with this constant torque, N.m, instead of running the test cycle: the
    /// crank starts at --start-rpm and turns under the torque against friction and its
    /// inertia for --duration s (the run of `tribo fmu export --input drive-torque`; 0 is a
    /// coast-down). Prints the crank speed and friction every --every s. Its laws run in this
    /// process.
    #[arg(long = "drive-torque", value_name = "NM", allow_negative_numbers = true, requires_all = ["start_rpm", "duration"], conflicts_with_all = ["steady", "csv", "timeseries", "crank_angle", "fmep"])]
    drive_torque: Option<f64>,
    /// Crank speed at the start of a --drive-torque run, rpm.
    #[arg(long = "start-rpm", value_name = "RPM", requires = "drive_torque")]
    start_rpm: Option<f64>,
    /// Length of a --drive-torque run, s.
    #[arg(long, value_name = "S", requires = "drive_torque")]
    duration: Option<f64>,
    /// Time between the samples a --drive-torque run reports, s (each one a communication
    /// point, as an FMU's step).
    #[arg(long, value_name = "S", default_value_t = 0.01)]
    every: f64,
    /// Worker process and its limits.
    #[command(flatten)]
    isolation: IsolationArgs,
}

/// The finest `--resolution-deg`: 72 000 samples over a 4-stroke cycle, far finer than any
/// friction trace needs, and a bound on what a run allocates for the traces.
const MIN_RESOLUTION_DEG: f64 = 0.01;

/// `--resolution-deg`, bounded where it is parsed.
fn resolution_deg(text: &str) -> Result<f64, String> {
    let r: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a number of degrees"))?;
    if (MIN_RESOLUTION_DEG..=10.0).contains(&r) {
        Ok(r)
    } else {
        Err(format!(
            "must be from {MIN_RESOLUTION_DEG} to 10 degrees (at most 72000 samples per cycle), got {r}"
        ))
    }
}

/// The arguments of `tribo compare`.
#[derive(Args, Clone, Serialize, Deserialize)]
struct CompareArgs {
    /// Rig file or bundled rig name (default: the bundled CRF 250 R rig).
    rig: Option<PathBuf>,
    /// Law set (bundled name or file); repeat to compare several (default: fedem-baseline,
    /// stribeck-duty and mixed-film).
    #[arg(long = "lawset")]
    lawsets: Vec<String>,
    /// Compare one more law set: the --base set with LAW on JOINT in place of the base's laws
    /// there (JOINT=LAW[:PARAMS.toml]; repeat for several joints). The other sets are untouched.
    #[arg(long = "law", value_name = "JOINT=LAW[:PARAMS_TOML_FILE]")]
    laws: Vec<String>,
    /// The law set --law builds on (bundled name or file; default: the first set compared).
    #[arg(long, value_name = "LAWSET", requires = "laws")]
    #[serde(default)]
    base: Option<String>,
    /// Name of the set --law adds (default: the law's name; several laws joined by `_`).
    #[arg(long, value_name = "NAME", requires = "laws")]
    #[serde(default)]
    name: Option<String>,
    /// In a worker: compare only the set --law adds (the others run in their own workers).
    #[arg(skip)]
    #[serde(default)]
    only_added: bool,
    /// Measured data, CSV speed_rpm,torque_nm,oil_temp_c (default: the bundled measurements of
    /// the rig, the thesis's table 10.4 on crf250r-motored; a rig without any needs --data).
    #[arg(long)]
    data: Option<String>,
    /// Use data whose `# rig:` line names another rig than the one compared.
    #[arg(long)]
    #[serde(default)]
    data_for_any_rig: bool,
    /// Score law sets with free parameters at their file's values instead of fitting them to
    /// the data first (each is then labelled "not fitted").
    #[arg(long)]
    #[serde(default)]
    no_fit: bool,
    /// Latin-hypercube start points of each set's calibration, besides its own values and the
    /// corners of its bounds.
    #[arg(long, default_value_t = tribo::fit::DEFAULT_STARTS as u32, value_parser = clap::value_parser!(u32).range(0..=64))]
    #[serde(default)]
    starts: u32,
    /// Override rig values, as for `run`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Output directory for comparison.csv, comparison.json, the plots and the fitted law sets.
    #[arg(long, default_value = "tribo-compare")]
    out: PathBuf,
    /// Steady state at each speed instead of the full test cycle (always, on a rig with a
    /// drivetrain).
    #[arg(long)]
    steady: bool,
    /// On a rig with a drivetrain: fit and score each set only on the points its transducer
    /// measured within its rating (the others are still run, marked `instrument_ok: false`).
    #[arg(long)]
    trusted_points_only: bool,
    /// Data never used in fitting (CSV as for --data), scored separately; repeatable.
    #[arg(long = "validate", value_name = "FILE")]
    validate: Vec<String>,
    /// Skip the leave-one-out refits and rank by in-sample RMSE (which rewards sets with
    /// many free parameters; the table says so).
    #[arg(long)]
    no_cv: bool,
    /// Print JSON instead of the table.
    #[arg(long)]
    json: bool,
    /// Print the correlation's table component by component for every set and speed (else a
    /// line per set; the whole table is in correlation.csv either way).
    #[arg(long)]
    #[serde(default)]
    correlation: bool,
    /// Worker processes and their limits.
    #[command(flatten)]
    isolation: IsolationArgs,
}

/// The arguments of `tribo mass-response`.
#[derive(Args, Clone, Serialize, Deserialize)]
struct MassResponseArgs {
    /// Rig file or bundled rig name (default: the bundled CRF 250 R rig).
    rig: Option<PathBuf>,
    /// Body to scale.
    #[arg(long, value_enum, default_value = "rod")]
    body: BodyArg,
    /// Mass (and inertia) scale factor.
    #[arg(long, default_value_t = 0.6, allow_negative_numbers = true)]
    scale: f64,
    /// A sweep of scale factors instead (e.g. 0.5,0.6,...,1.1); writes a plot.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    scales: Option<Vec<f64>>,
    /// Law set (bundled name or file); repeat for several (default: fedem-baseline,
    /// stribeck-duty and mixed-film).
    #[arg(long = "lawset")]
    lawsets: Vec<String>,
    /// Override rig values, as for `run`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Steady state at each speed instead of the full test cycle.
    #[arg(long)]
    steady: bool,
    /// Output directory for mass_response.json (and mass_sweep.svg with --scales).
    #[arg(long, default_value = "tribo-mass-response")]
    out: PathBuf,
    /// Print JSON instead of the table.
    #[arg(long)]
    json: bool,
    /// Worker processes and their limits.
    #[command(flatten)]
    isolation: IsolationArgs,
}

/// The arguments of `tribo fit`.
#[derive(Args, Clone, Serialize, Deserialize)]
struct FitArgs {
    /// Rig file or bundled rig name (default: the bundled CRF 250 R rig).
    rig: Option<PathBuf>,
    /// Law set to calibrate (bundled name or file).
    #[arg(long)]
    lawset: String,
    /// Parameters to fit, JOINT.LAW.PARAM,... (default: those the law set marks free).
    #[arg(long, value_delimiter = ',')]
    params: Option<Vec<String>>,
    /// Measured data, CSV speed_rpm,torque_nm,oil_temp_c (default: the bundled measurements of
    /// the rig, the thesis's table 10.4 on crf250r-motored); repeat for several runs: one
    /// parameter set is fitted to all, each point at its own oil temperature.
    #[arg(long = "data", value_name = "FILE")]
    data: Vec<String>,
    /// Use data whose `# rig:` line names another rig than the one fitted.
    #[arg(long)]
    #[serde(default)]
    data_for_any_rig: bool,
    /// Data never used in fitting, scored with the fitted values; repeatable.
    #[arg(long = "validate", value_name = "FILE")]
    validate: Vec<String>,
    /// Latin-hypercube start points over the bounds, besides the law set's own values and the
    /// corners of the bounds (all of them up to four parameters, 16 beyond); the best result is
    /// polished and kept, and the spread of the others reported.
    #[arg(long, default_value_t = tribo::fit::DEFAULT_STARTS as u32, value_parser = clap::value_parser!(u32).range(0..=64))]
    starts: u32,
    /// Skip the leave-one-out cross-validation.
    #[arg(long)]
    no_cv: bool,
    /// Override rig values, as for `run`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Where to write the calibrated law set (default: <lawset>-fitted.toml).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print JSON instead of the report.
    #[arg(long)]
    json: bool,
    /// Worker processes and their limits.
    #[command(flatten)]
    isolation: IsolationArgs,
}

/// The arguments of `tribo sweep`.
#[derive(Args, Clone, Serialize, Deserialize)]
struct SweepArgs {
    /// Rig file or bundled rig name (default: the bundled CRF 250 R rig).
    rig: Option<PathBuf>,
    /// Law set (bundled name or file); repeat for several (default: fedem-baseline,
    /// stribeck-duty and mixed-film).
    #[arg(long = "lawset")]
    lawsets: Vec<String>,
    /// Attach a law to every law set: JOINT=LAW[:PARAMS.toml] (added to the set's laws there).
    #[arg(long = "law", value_name = "JOINT=LAW[:PARAMS_TOML_FILE]")]
    laws: Vec<String>,
    /// Oil temperatures, C, comma-separated (within the viscosity model's valid range).
    #[arg(
        long,
        value_name = "C,C,...",
        default_value = "40,50,60,70,80,90,100,110",
        allow_hyphen_values = true
    )]
    temps: String,
    /// Engine speeds, rpm, comma-separated (default: the plateau speeds of the rig's own test
    /// cycle, 3000-9000 rpm on the CRF 250 R; at most the rig's max_speed_rpm).
    #[arg(long, value_name = "RPM,RPM,...", allow_hyphen_values = true)]
    speeds: Option<String>,
    /// Another oil: a TOML file with an [oil] table (name, grade, source, viscosity,
    /// density_kg_m3), applied before --set.
    #[arg(long, value_name = "FILE.toml")]
    oil: Option<PathBuf>,
    /// Override rig values, as for `run` (e.g. another oil:
    /// 'oil.viscosity={model="vogel", k_cst=0.1, theta1_c=1100, theta2_c=120}').
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Output directory for sweep.csv, sweep.json and sweep_<lawset>.svg.
    #[arg(long, default_value = "tribo-sweep")]
    out: PathBuf,
    /// Print JSON instead of the tables.
    #[arg(long)]
    json: bool,
    /// Worker processes and their limits.
    #[command(flatten)]
    isolation: IsolationArgs,
}

/// The arguments of `tribo new-law`.
#[derive(Args)]
struct NewLawArgs {
    /// Law name: lowercase letters, digits and hyphens (e.g. `my-law`).
    name: String,
    /// Language of the law: rust (a cargo crate), c, cpp or fortran (a folder with the law, a
    /// Makefile and a unit test, built against the checkout's tribo_law.h).
    #[arg(long, default_value = "rust", value_name = "rust|c|cpp|fortran")]
    lang: scaffold::Lang,
    /// Directory to create the law in (default: the workspace's plugins/ for Rust, the current
    /// directory for C, C++ and Fortran).
    #[arg(long)]
    dir: Option<PathBuf>,
}

/// The arguments of `tribo check-law`.
#[derive(Args)]
struct CheckLawArgs {
    /// Law library file (.so, .dylib, .dll) or law name (found like every other command's laws).
    law: String,
    /// TOML table of parameters to check the law with (missing ones take their defaults).
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// The law feeds energy in on purpose, for this reason: the dissipation check is skipped
    /// and the reason shown.
    #[arg(long, value_name = "REASON")]
    active: Option<String>,
    /// Machine-readable JSON report instead of a table.
    #[arg(long)]
    json: bool,
    /// Worker process and its limits.
    #[command(flatten)]
    isolation: IsolationArgs,
}

/// The arguments of `tribo plot-law`.
#[derive(Args)]
struct PlotLawArgs {
    /// Law library file or law name.
    law: String,
    /// TOML table of parameters (missing ones take their defaults).
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Joint of the bundled rig whose contact geometry the law sits on: main_a, main_b,
    /// big_end, small_end (revolute: torque) or piston (prismatic: force).
    #[arg(long, default_value = "piston")]
    joint: String,
    /// SVG file to write (default: plot_<law>.svg in the current directory).
    #[arg(long, value_name = "FILE.svg")]
    out: Option<PathBuf>,
    /// Worker process and its limits.
    #[command(flatten)]
    isolation: IsolationArgs,
}

/// The body a mass study scales, as the command line spells it.
#[derive(Clone, Copy, clap::ValueEnum, Serialize, Deserialize)]
enum BodyArg {
    /// The connecting rod (mass and inertia).
    Rod,
    /// The piston assembly (mass).
    Piston,
    /// The crankshaft (mass and inertia).
    Crank,
}

impl From<BodyArg> for tribo::study::ScaledBody {
    fn from(b: BodyArg) -> Self {
        match b {
            BodyArg::Rod => Self::Rod,
            BodyArg::Piston => Self::Piston,
            BodyArg::Crank => Self::Crank,
        }
    }
}

/// The rig (default: the bundled CRF 250 R rig) and law sets (default: the two bundled ones)
/// a study command works on.
fn study_inputs(
    rig: Option<PathBuf>,
    sets: &[String],
    lawsets: Vec<String>,
) -> anyhow::Result<(tribo::rig::Rig, Vec<tribo::lawset::LawSet>)> {
    let rig_path = rig.unwrap_or_else(|| PathBuf::from(tribo::bundled::DEFAULT_RIG));
    let rig = tribo::rig::load_rig(&rig_path, sets)?;
    let names: Vec<String> = if lawsets.is_empty() {
        tribo::bundled::DEFAULT_LAWSETS
            .iter()
            .map(|s| s.to_string())
            .collect()
    } else {
        lawsets
    };
    let loaded = names
        .iter()
        .map(|n| tribo::lawset::LawSet::load(n))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((rig, loaded))
}

/// `--oil FILE` as `--set oil.KEY=VALUE` overrides, placed before the user's own `--set`s so
/// those still win.
fn with_oil_file(oil: Option<&std::path::Path>, sets: Vec<String>) -> anyhow::Result<Vec<String>> {
    let Some(path) = oil else {
        return Ok(sets);
    };
    let mut all = tribo::rig::oil_file_sets(path)?;
    all.extend(sets);
    Ok(all)
}

/// The arguments of `tribo modes`.
#[derive(Args)]
struct ModesArgs {
    /// Rig file (TOML) or bundled rig name; it must have a `[drivetrain]` or an
    /// `[engine.crankshaft]`.
    rig: PathBuf,
    /// Override any rig value by its dotted path, e.g. drivetrain.motor.inertia_kg_m2=0.003.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Print JSON (`inertias`, `springs`, `modes`) instead of a table.
    #[arg(long)]
    json: bool,
    /// Also write the Campbell diagram (engine orders 0.5-12, the modes, the plateaus) here.
    #[arg(long, value_name = "FILE.svg")]
    svg: Option<PathBuf>,
}

/// `tribo modes`: the drivetrain's modes as a table or JSON, and the Campbell diagram.
fn cmd_modes(a: ModesArgs) -> anyhow::Result<()> {
    let rig = tribo::rig::load_rig(&a.rig, &a.sets)?;
    let model = rig.model();
    let (chain, hold) = tribo::sim::drivetrain_chain(model)
        .map_err(|e| anyhow::anyhow!("{e}"))?
        .with_context(|| {
            format!(
                "rig `{}` has neither a [drivetrain] nor an elastic crankshaft ([engine.crankshaft]): `tribo modes` analyses the torsional chain from the motor to the crank (e.g. the bundled crf250r-testbed, or rigs/inline4-4b11-elastic.toml)",
                model.name
            )
        })?;
    let plateaus: Vec<f64> = tribo::cycle::Cycle::new(&model.cycle.segments())
        .plateaus()
        .iter()
        .map(|p| p.speed_rpm)
        .collect();
    let report = chain.report(&model.name, hold, &plateaus);
    if let Some(path) = &a.svg {
        tribo::modes::write_campbell(&report, path)
            .with_context(|| format!("writing the Campbell diagram {}", path.display()))?;
    }
    let text = if a.json {
        format!("{}\n", serde_json::to_string_pretty(&report)?)
    } else {
        tribo::modes::text(&report)
    };
    emit(&text)
}

/// The options every command shares.
struct Globals {
    /// Extra plugin libraries or directories (`--plugin`).
    plugins: Vec<PathBuf>,
    /// No progress display (`--quiet`).
    quiet: bool,
}

impl Globals {
    /// Every law plugin found (`--plugin`, `TRIBO_PLUGIN_PATH`, the executable's directory);
    /// only `--plugin` files are opened now, the others when a law is asked for. Plugin
    /// directories and files others can write are warned about on standard error.
    fn registry(&self) -> anyhow::Result<LawRegistry> {
        let registry = discover(&self.plugins).context("loading law plugins")?;
        laws::print_warnings(registry.warnings());
        Ok(registry)
    }
}

/// Run the command the user asked for.
fn run(cli: Cli) -> anyhow::Result<()> {
    let g = Globals {
        plugins: cli.plugins,
        quiet: cli.quiet,
    };
    match cli.command {
        Command::Laws(a) => cmd_laws(&g, a),
        Command::Run(a) => cmd_run(&g, a),
        Command::Compare(a) => cmd_compare(&g, a),
        Command::MassResponse(a) => cmd_mass_response(&g, a),
        Command::Fit(a) => cmd_fit(&g, a),
        Command::Modes(a) => cmd_modes(a),
        Command::Sweep(a) => cmd_sweep(&g, a),
        Command::NewLaw(a) => cmd_new_law(a),
        Command::CheckLaw(a) => cmd_check_law(&g, a),
        Command::PlotLaw(a) => cmd_plot_law(&g, a),
        Command::Worker => cmd_worker(&g),
        Command::Fmu(FmuCommand::Export(a)) => cmd_fmu_export(&g, a),
        Command::FmuWorker(a) => cmd_fmu_worker(&a),
    }
}

/// `tribo laws`: the laws found, as a table or JSON. Listing opens every plugin library, so it
/// runs in a worker process; a library whose loading ends, crashes or hangs that worker is
/// skipped with a warning naming it, and the listing is made again without it.
fn cmd_laws(g: &Globals, a: LawsArgs) -> anyhow::Result<()> {
    let listed = isolate::listing::skipping_unloadable(|skip| {
        let plugins: Vec<PathBuf> = g
            .plugins
            .iter()
            .filter(|p| !skip.iter().any(|(s, _)| s == *p))
            .cloned()
            .collect();
        let job = laws::LawsJob {
            json: a.json,
            skip: skip.to_vec(),
        };
        let mut worker = isolate::Worker::start(
            isolate::worker_command(&plugins),
            isolate::Limits::default(),
        )?;
        let reply = worker.call::<_, WorkerOutput>(&WorkerJob::Laws(job), &mut |e| {
            isolate::show_event("", &e);
            Ok(())
        });
        worker.finish();
        match reply? {
            WorkerOutput::Laws(text) => Ok(text),
            _ => Err(WorkerFailure::Internal(
                "a worker answered another job's question".into(),
            )),
        }
    });
    match listed {
        Ok((text, skipped)) => {
            // A skipped `--plugin` file is not in the worker's listing: warn here.
            let given: Vec<String> = skipped
                .iter()
                .filter(|(p, _)| g.plugins.contains(p))
                .map(|(p, why)| {
                    format!(
                        "skipped a plugin file that cannot be used: `{}` was not opened: {why}",
                        p.display()
                    )
                })
                .collect();
            laws::print_warnings(&given);
            emit(&text)
        }
        Err(WorkerFailure::Study(message)) => anyhow::bail!("{message}"),
        Err(e) => anyhow::bail!("listing the laws: {e}"),
    }
}

/// A `tribo run` as a worker (or this process) runs it: the rig and its laws as the user gave
/// them (`--oil` already turned into `--set`s), already checked by the parent.
#[derive(Serialize, Deserialize)]
struct RunJob {
    rig: PathBuf,
    sets: Vec<String>,
    lawset: Option<String>,
    laws: Vec<String>,
    steady: bool,
    /// Stream the time series (to the parent, or into the writer given).
    timeseries: bool,
    /// `--crank-angle` at this resolution, degrees.
    crank_angle_deg: Option<f64>,
    /// `--require-laws`: refuse a rig with no law on any joint.
    require_laws: bool,
}

/// What a run hands back: its result and the crank-angle traces asked for. The result's
/// fields kept out of its serde form (they vary run to run) travel beside it.
#[derive(Serialize, Deserialize)]
struct RunOutput {
    result: tribo::sim::RunResult,
    traces: Option<Vec<tribo::sim::CrankAngleTrace>>,
    law_time: Vec<tribo::sim::LawTime>,
    rejected_steps: u64,
    replayed_steps: u64,
}

impl RunJob {
    /// The rig with its law set and `--law`s attached (no plugin opened yet).
    fn rig(&self) -> anyhow::Result<tribo::rig::Rig> {
        rig_with_laws(&self.rig, &self.sets, self.lawset.as_deref(), &self.laws)
    }

    /// Bind the laws from `registry` and run, the time series (if asked for) into `series`.
    fn simulate(
        &self,
        registry: &LawRegistry,
        progress: tribo::progress::Position,
        series: Option<&mut dyn std::io::Write>,
    ) -> anyhow::Result<RunOutput> {
        let rig = self.rig()?;
        let mut sim = tribo::rig::simulation(&rig, registry)?;
        if self.require_laws && sim.law_count() == 0 {
            anyhow::bail!(
                "--require-laws: rig `{}` has no law on any joint; attach laws with --lawset NAME or --law JOINT=LAW",
                rig.file.name
            );
        }
        sim.report_progress(progress);
        let result = match series {
            _ if self.steady => sim.run_steady()?,
            Some(out) if self.timeseries => {
                let mut series = tribo::timeseries::TimeSeries::new(out);
                sim.run_with(&mut series)?
            }
            _ => sim.run()?,
        };
        let traces = match self.crank_angle_deg {
            Some(r) => Some(sim.crank_angle_traces(r)?),
            None => None,
        };
        Ok(RunOutput {
            law_time: result.law_time.clone(),
            rejected_steps: result.rejected_steps,
            replayed_steps: result.replayed_steps,
            result,
            traces,
        })
    }
}

/// `tribo run`: one rig through its cycle (or steady state), reported as a table or JSON, with
/// optional CSV files and time series; the laws run in a worker process unless `--in-process`.
fn cmd_run(g: &Globals, a: RunArgs) -> anyhow::Result<()> {
    if let (Some(torque), Some(rpm), Some(duration)) = (a.drive_torque, a.start_rpm, a.duration) {
        let run = tribo::torque_run::TorqueRun {
            drive_torque_nm: torque,
            start_speed_rad_s: rpm * std::f64::consts::PI / 30.0,
            duration_s: duration,
            every_s: a.every,
        };
        return cmd_run_torque(g, a, run);
    }
    let mut out_text = String::new();
    let RunArgs {
        rig,
        steady,
        json,
        csv,
        timeseries,
        crank_angle,
        fmep,
        resolution_deg,
        require_laws,
        isolation,
        ..
    } = a;
    let limits = isolation.limits()?;
    let RigArgs {
        rig,
        laws,
        sets,
        oil,
        lawset,
    } = rig;
    let job = RunJob {
        rig,
        sets: with_oil_file(oil.as_deref(), sets)?,
        lawset,
        laws,
        steady,
        timeseries: timeseries.is_some(),
        crank_angle_deg: crank_angle.as_ref().map(|_| resolution_deg),
        require_laws,
    };
    // Every input is checked here, before any law is loaded.
    let rig = job.rig()?;
    if let Some(dir) = &csv {
        tribo::output::check_result_dir(dir, "--csv")
            .with_context(|| format!("writing CSV into {}", dir.display()))?;
    }
    if let Some(dir) = &fmep {
        tribo::output::check_result_dir(dir, "--fmep")
            .with_context(|| format!("writing FMEP into {}", dir.display()))?;
    }
    if let Some(dir) = &crank_angle {
        tribo::output::check_result_dir(dir, "--crank-angle")
            .with_context(|| format!("writing crank-angle results into {}", dir.display()))?;
    }
    let mut series = match &timeseries {
        Some(path) => Some(
            tribo::output::AtomicFile::create(path)
                .with_context(|| format!("creating {}", path.display()))?,
        ),
        None => None,
    };
    let progress = Progress::start("simulating the test cycle", Some(1000), g.quiet);
    let output = if isolation.in_process {
        guard::watch(limits);
        let registry = g.registry()?;
        job.simulate(
            &registry,
            progress.position(),
            series.as_mut().map(|f| f as &mut dyn std::io::Write),
        )?
    } else {
        let position = progress.position();
        let mut write_error = None;
        let output = g.in_worker(
            limits,
            &WorkerJob::Run(job),
            "the run failed",
            &mut |e| match e {
                Event::Data(bytes) => {
                    if let (Some(f), None) = (series.as_mut(), &write_error) {
                        use std::io::Write as _;
                        write_error = f.write_all(bytes).err();
                    }
                }
                Event::Progress(p) => position.set(p),
                other => isolate::show_event("", &other),
            },
            |o| match o {
                WorkerOutput::Run(r) => Some(*r),
                _ => None,
            },
        )?;
        if let (Some(e), Some(path)) = (write_error, &timeseries) {
            return Err(anyhow::Error::new(e).context(format!("writing {}", path.display())));
        }
        output
    };
    drop(progress);
    if let (Some(file), Some(path)) = (series, &timeseries) {
        file.commit()
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let RunOutput {
        mut result,
        traces,
        law_time,
        rejected_steps,
        replayed_steps,
    } = output;
    result.law_time = law_time;
    result.rejected_steps = rejected_steps;
    result.replayed_steps = replayed_steps;
    // A trace's warnings (a stateful cycle that never repeated) are reported with the run's,
    // once where the steady run already gave the same one.
    for w in traces.iter().flatten().flat_map(|t| &t.warnings) {
        if !result.warnings.contains(w) {
            result.warnings.push(format!("--crank-angle: {w}"));
        }
    }
    if let Some(dir) = &csv {
        tribo::results::write_csv(&result, dir)
            .with_context(|| format!("writing CSV into {}", dir.display()))?;
    }
    if let Some(dir) = &fmep {
        tribo::results::write_fmep(&result, dir)
            .with_context(|| format!("writing FMEP into {}", dir.display()))?;
    }
    if let (Some(dir), Some(traces)) = (&crank_angle, &traces) {
        tribo::results::write_crank_angle(traces, dir)
            .with_context(|| format!("writing crank-angle results into {}", dir.display()))?;
    }
    if json {
        writeln!(out_text, "{}", serde_json::to_string_pretty(&result)?)?;
    } else {
        write!(
            out_text,
            "{}",
            tribo::report::wrap(
                &format!("oil: {}", rig.file.oil.describe()),
                tribo::report::MAX_COLUMNS,
                "     "
            )
        )?;
        write!(out_text, "{}", tribo::report::to_text(&result))?;
        write!(out_text, "{}", tribo::modes::instrument_text(&result))?;
        write!(out_text, "{}", tribo::beside::run_text(&result))?;
    }
    emit(&out_text)
}

/// `tribo run --drive-torque`: the crank driven by a constant torque from a start speed, its
/// laws in this process (under the run's limits).
fn cmd_run_torque(
    g: &Globals,
    a: RunArgs,
    run: tribo::torque_run::TorqueRun,
) -> anyhow::Result<()> {
    run.check().map_err(anyhow::Error::msg)?;
    let limits = a.isolation.limits()?;
    let rig = a.rig.load()?;
    guard::watch(limits);
    let registry = std::sync::Arc::new(g.registry()?);
    let (samples, warnings) = run
        .run(rig.model(), registry)
        .context("the drive-torque run failed")?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    let text = if a.json {
        format!(
            "{}\n",
            serde_json::to_string_pretty(&serde_json::json!({ "samples": samples }))?
        )
    } else {
        tribo::torque_run::to_text(&samples)
    };
    emit(&text)
}

/// The closing line of a study's text report: the directory and the files written into it,
/// wrapped to the report width.
fn wrote_into(out: &std::path::Path, files: &[String]) -> String {
    tribo::report::wrap(
        &format!("wrote into {}: {}", out.display(), files.join(", ")),
        tribo::report::MAX_COLUMNS,
        "  ",
    )
}

/// The law-set names (bundled names or files) a study command runs: those given, or the
/// bundled defaults.
fn lawset_specs(given: &[String]) -> Vec<String> {
    if given.is_empty() {
        tribo::bundled::DEFAULT_LAWSETS
            .iter()
            .map(|s| s.to_string())
            .collect()
    } else {
        given.to_vec()
    }
}

/// What a worker process is asked to do: check every law set's laws and parameters, or run one
/// study command for one law set.
#[derive(Serialize, Deserialize)]
enum WorkerJob {
    /// Load the plugins and bind every set's laws (names, parameters), running nothing.
    Check(Vec<SetSource>),
    /// `compare` for one law set.
    Compare(CompareArgs),
    /// `mass-response` for one law set.
    MassResponse(MassResponseArgs),
    /// `sweep` for one law set.
    Sweep(SweepArgs),
    /// `fit`.
    Fit(FitArgs),
    /// `run`.
    Run(RunJob),
    /// `check-law`.
    CheckLaw(CheckJob),
    /// `plot-law`: the law's curves.
    PlotLaw(PlotJob),
    /// `laws`: the listing.
    Laws(laws::LawsJob),
    /// `fmu export`'s check: the rig's laws bound, nothing run.
    Bind(RunJob),
}

/// What a worker process hands back.
#[derive(Serialize, Deserialize)]
enum WorkerOutput {
    /// Every law set binds.
    Checked,
    /// A one-set comparison.
    Compare(Box<tribo::study::Comparison>),
    /// A one-set mass response.
    MassResponse(Vec<tribo::study::MassResponse>),
    /// A one-set sweep.
    Sweep(Box<tribo::study::Sweep>),
    /// The fit's report and the calibrated law set as TOML.
    Fit(Box<tribo::fit::FitResult>, String),
    /// A run's results.
    Run(Box<RunOutput>),
    /// A law's conformance report.
    CheckLaw(CheckOutput),
    /// A law's force-velocity curves.
    PlotLaw(Box<tribo::check::LawCurves>),
    /// The `laws` listing, as printed.
    Laws(String),
}

/// Where one law set of a study comes from, for the check job.
#[derive(Clone, Serialize, Deserialize)]
struct SetSource {
    /// Rig file or bundled name.
    rig: Option<PathBuf>,
    /// `--set` overrides (with `--oil` already turned into them).
    sets: Vec<String>,
    /// The law set (bundled name or file).
    lawset: String,
    /// `--law` attachments added to it.
    laws: Vec<String>,
    /// `compare --law`: the new set's name; `lawset` is its base and `laws` replace the
    /// base's laws on their joints.
    #[serde(default)]
    added_as: Option<String>,
}

impl SetSource {
    /// The law set this source names, with its `--law`s added (or, for `compare --law`'s new
    /// set, in place of the base's laws there).
    fn load(&self) -> anyhow::Result<tribo::lawset::LawSet> {
        let mut set = tribo::lawset::LawSet::load(&self.lawset)?;
        if self.added_as.is_some() {
            return Ok(tribo::study::set_with_laws(
                &set,
                &self.laws,
                self.added_as.as_deref(),
            )?);
        }
        set.add_law_args(&self.laws)?;
        Ok(set)
    }
}

/// Check every law set against the plugins before any run: each law exists, its parameters
/// have the right names, types and ranges, and its joint exists. Only the laws' descriptions are
/// read; no instance is created, so a law that misbehaves when created or run fails its own
/// set later, not the whole study.
fn check_sources(sources: &[SetSource], registry: &LawRegistry) -> anyhow::Result<()> {
    for s in sources {
        let rig_path = s
            .rig
            .clone()
            .unwrap_or_else(|| PathBuf::from(tribo::bundled::DEFAULT_RIG));
        let rig = tribo::rig::load_rig(&rig_path, &s.sets)?;
        tribo::study::check_lawsets_described(&rig, &[s.load()?], registry)?;
    }
    Ok(())
}

impl Globals {
    /// Check every law set in one worker process (so even loading a plugin never happens in
    /// this one), then run `jobs`, one worker process each, `labels` naming them in notes; the
    /// results in the order of `jobs`.
    fn run_isolated(
        &self,
        sources: Vec<SetSource>,
        jobs: Vec<WorkerJob>,
        labels: &[String],
        limits: isolate::Limits,
    ) -> anyhow::Result<Vec<Result<WorkerOutput, WorkerFailure>>> {
        self.in_worker(
            limits,
            &WorkerJob::Check(sources),
            "checking the law sets before running them",
            &mut |e| isolate::show_event("checking the law sets: ", &e),
            |o| matches!(o, WorkerOutput::Checked).then_some(()),
        )?;
        let command = || isolate::worker_command(&self.plugins);
        // The result folder is watched while the sets run: what appears there is a law's.
        let watched = jobs.iter().find_map(|j| match j {
            WorkerJob::Compare(a) => Some(a.out.clone()),
            WorkerJob::MassResponse(a) => Some(a.out.clone()),
            WorkerJob::Sweep(a) => Some(a.out.clone()),
            _ => None,
        });
        Ok(isolate::run_all_watched(
            &jobs,
            &command,
            limits,
            &|i, e| {
                let label = labels.get(i).map_or("", String::as_str);
                isolate::show_event(label, &e)
            },
            watched.as_deref(),
        ))
    }

    /// Run `job` in one worker process with `limits`; its events go to `events`. A failure of
    /// the job itself is its own message; any other (a crash, a limit, an exit) is prefixed
    /// with `what`.
    fn in_worker<T>(
        &self,
        limits: isolate::Limits,
        job: &WorkerJob,
        what: &str,
        events: &mut dyn FnMut(Event<'_>),
        pick: impl FnOnce(WorkerOutput) -> Option<T>,
    ) -> anyhow::Result<T> {
        let mut worker = isolate::Worker::start(isolate::worker_command(&self.plugins), limits)
            .map_err(|e| anyhow::anyhow!("{what}: {e}"))?;
        let reply = worker.call::<_, WorkerOutput>(job, &mut |e| {
            events(e);
            Ok(())
        });
        worker.finish();
        match reply {
            Ok(o) => {
                pick(o).ok_or_else(|| anyhow::anyhow!("a worker answered another job's question"))
            }
            Err(WorkerFailure::Study(message)) => Err(anyhow::anyhow!("{message}")),
            Err(e) => Err(anyhow::anyhow!("{what}: {e}")),
        }
    }
}

/// The label of law set `name` in notes of a study's workers.
fn set_label(name: &str) -> String {
    format!("law set `{name}`: ")
}

/// The failures of an isolated study as one error: after the other sets' results were written
/// into `out`, or, with `None`, when no set gave results and nothing was written.
fn failures_error(
    failed: &[tribo::study::FailedSet],
    total: usize,
    out: Option<&std::path::Path>,
) -> anyhow::Result<()> {
    if failed.is_empty() {
        return Ok(());
    }
    let mut text = match out {
        Some(out) => format!(
            "{} of {total} law sets failed; the results of the others were written into {}:",
            failed.len(),
            out.display()
        ),
        None => format!("all {total} law sets failed; nothing was written:"),
    };
    for f in failed {
        let _ = write!(text, "\n  law set `{}`: {}", f.lawset, f.message);
    }
    Err(anyhow::anyhow!(text))
}

/// A law set that gave no results, with the worker's reason (a study error's own "law set `x`:"
/// prefix dropped, since the report names the set).
fn failed_set(ls: &tribo::lawset::LawSet, e: WorkerFailure) -> tribo::study::FailedSet {
    let prefix = format!("law set `{}`: ", ls.name());
    let message = e.to_string();
    tribo::study::FailedSet {
        lawset: ls.name().to_string(),
        message: message
            .strip_prefix(&prefix)
            .map_or(message.clone(), str::to_string),
    }
}

/// `compare` for the law sets of `a`, in this process.
fn compare_study(
    a: &CompareArgs,
    registry: &LawRegistry,
) -> anyhow::Result<tribo::study::Comparison> {
    let (rig, sets_loaded) = compare_inputs(a)?;
    let data = tribo::study::DataRun::read(&data_arg(a.data.as_deref(), &rig)?)?;
    let options = tribo::study::CompareOptions {
        steady: a.steady,
        no_cv: a.no_cv,
        no_fit: a.no_fit,
        starts: a.starts as usize,
        validate: read_data_runs(&a.validate)?,
        data_for_any_rig: a.data_for_any_rig,
        trusted_points_only: a.trusted_points_only,
    };
    Ok(tribo::study::compare(
        &rig,
        &sets_loaded,
        &data,
        registry,
        &options,
    )?)
}

/// `tribo compare`: law sets side by side against measured data; table or JSON on stdout,
/// CSV, JSON and plots in the output directory.
fn cmd_compare(g: &Globals, a: CompareArgs) -> anyhow::Result<()> {
    let mut out_text = String::new();
    // Every input is read and checked before anything runs.
    let (rig, sets_loaded) = compare_inputs(&a)?;
    let sources = a.sources();
    let data = tribo::study::DataRun::read(&data_arg(a.data.as_deref(), &rig)?)?;
    let validate = read_data_runs(&a.validate)?;
    // Once, here, before any worker: data measured on another rig, or whose cycle the rig
    // cannot run, fail the command.
    for d in std::iter::once(&data).chain(&validate) {
        tribo::study::check_data_rig(&rig, d, a.data_for_any_rig)?;
        tribo::study::check_data(&rig, d)?;
    }
    tribo::output::check_result_dir(&a.out, "--out")?;
    let progress = Progress::start("comparing law sets", None, g.quiet);
    let cmp = if a.isolation.in_process {
        guard::watch(a.isolation.limits()?);
        let registry = g.registry()?;
        check_sources(&sources, &registry)?;
        compare_study(&a, &registry)?
    } else {
        let jobs = sources
            .iter()
            .map(|s| {
                WorkerJob::Compare(CompareArgs {
                    lawsets: vec![s.lawset.clone()],
                    laws: s.laws.clone(),
                    base: s.added_as.is_some().then(|| s.lawset.clone()),
                    name: s.added_as.clone(),
                    only_added: s.added_as.is_some(),
                    ..a.clone()
                })
            })
            .collect();
        let labels: Vec<String> = sets_loaded.iter().map(|l| set_label(l.name())).collect();
        let results = g.run_isolated(sources.clone(), jobs, &labels, a.isolation.limits()?)?;
        merge_comparisons(&sets_loaded, results, a.no_cv)?
    };
    drop(progress);
    let out = &a.out;
    tribo::results::write_comparison(&cmp, out)
        .with_context(|| format!("writing results into {}", out.display()))?;
    if a.json {
        writeln!(out_text, "{}", serde_json::to_string_pretty(&cmp)?)?;
    } else {
        write!(out_text, "{}", tribo::report::comparison_text(&cmp))?;
        if a.correlation {
            write!(out_text, "{}", tribo::beside::comparison_text(&cmp))?;
        } else {
            write!(out_text, "{}", tribo::beside::comparison_summary(&cmp))?;
        }
        let mut files = vec![
            "comparison.csv".to_string(),
            "scores.csv".into(),
            "validation.csv".into(),
            "comparison.json".into(),
            "torque_vs_speed.svg".into(),
            "contributions_*.svg".into(),
            "piston_regimes.svg".into(),
            "correlation.csv".into(),
            "correlation_*.svg".into(),
        ];
        files.extend(cmp.sets.iter().filter_map(tribo::results::fitted_file));
        write!(out_text, "\n{}", wrote_into(out, &files))?;
    }
    emit(&out_text)?;
    failures_error(&cmp.failed, sources.len(), Some(out))?;
    planted_in_process(a.isolation.in_process, out)
}

impl CompareArgs {
    /// Where each law set of this comparison comes from: the sets named (or the bundled
    /// defaults) as they are, then, with `--law`, the new set built on `--base` (default: the
    /// first set). A worker given `only_added` runs the new set alone.
    fn sources(&self) -> Vec<SetSource> {
        let specs = lawset_specs(&self.lawsets);
        let source = |lawset: &str, laws: Vec<String>, added_as: Option<String>| SetSource {
            rig: self.rig.clone(),
            sets: self.sets.clone(),
            lawset: lawset.to_string(),
            laws,
            added_as,
        };
        let mut out: Vec<SetSource> = if self.only_added {
            Vec::new()
        } else {
            specs.iter().map(|l| source(l, Vec::new(), None)).collect()
        };
        if !self.laws.is_empty() {
            let base = self.base.clone().unwrap_or_else(|| specs[0].clone());
            // The default name is the laws' names; `set_with_laws` derives it when `None`.
            let name = self.name.clone().unwrap_or_else(|| added_name(&self.laws));
            out.push(source(&base, self.laws.clone(), Some(name)));
        }
        out
    }
}

/// The default name of `compare --law`'s new set: the laws' names joined by `_` (the
/// arguments' syntax is checked when the set is built).
fn added_name(laws: &[String]) -> String {
    laws.iter()
        .filter_map(|a| a.split_once('=').map(|(_, l)| l))
        .map(|l| l.split_once(':').map_or(l, |(law, _)| law))
        .collect::<Vec<_>>()
        .join("_")
}

/// The rig and the law sets of a comparison ([`CompareArgs::sources`]), their names checked
/// distinct.
fn compare_inputs(
    a: &CompareArgs,
) -> anyhow::Result<(tribo::rig::Rig, Vec<tribo::lawset::LawSet>)> {
    let rig_path = a
        .rig
        .clone()
        .unwrap_or_else(|| PathBuf::from(tribo::bundled::DEFAULT_RIG));
    let rig = tribo::rig::load_rig(&rig_path, &a.sets)?;
    let sets = a
        .sources()
        .iter()
        .map(SetSource::load)
        .collect::<anyhow::Result<Vec<_>>>()?;
    if let (false, Some((added, others))) = (a.laws.is_empty(), sets.split_last()) {
        if let Some(same) = others.iter().find(|s| s.name() == added.name()) {
            anyhow::bail!(
                "--law: the new law set would be named `{}`, like the law set {}; give it another name with --name",
                added.name(),
                same.path.display()
            );
        }
    }
    tribo::study::check_unique_names(&sets)?;
    Ok((rig, sets))
}

/// One comparison from the one-set comparisons of the workers: the sets in the order given,
/// ranked together, and the failed ones listed. An error if none gave results.
fn merge_comparisons(
    lawsets: &[tribo::lawset::LawSet],
    results: Vec<Result<WorkerOutput, WorkerFailure>>,
    no_cv: bool,
) -> anyhow::Result<tribo::study::Comparison> {
    let (parts, failed) = split_replies(lawsets, results, |o| match o {
        WorkerOutput::Compare(c) => Some(*c),
        _ => None,
    })?;
    let mut parts = parts.into_iter();
    let Some(mut cmp) = parts.next() else {
        failures_error(&failed, lawsets.len(), None)?;
        anyhow::bail!("no law set to compare");
    };
    cmp.sets.extend(parts.flat_map(|c| c.sets));
    cmp.failed = failed;
    cmp.rank(no_cv);
    Ok(cmp)
}

/// The workers' replies, one per law set in order, split into the expected outputs (`pick`
/// says which variant that is) and the sets that failed.
fn split_replies<T>(
    lawsets: &[tribo::lawset::LawSet],
    results: Vec<Result<WorkerOutput, WorkerFailure>>,
    pick: impl Fn(WorkerOutput) -> Option<T>,
) -> anyhow::Result<(Vec<T>, Vec<tribo::study::FailedSet>)> {
    let mut parts = Vec::new();
    let mut failed = Vec::new();
    for (ls, r) in lawsets.iter().zip(results) {
        match r {
            Ok(o) => parts.push(
                pick(o)
                    .ok_or_else(|| anyhow::anyhow!("a worker answered another job's question"))?,
            ),
            Err(e) => failed.push(failed_set(ls, e)),
        }
    }
    Ok((parts, failed))
}

/// `mass-response` for the law sets of `a`, in this process.
fn mass_study(
    a: &MassResponseArgs,
    registry: &LawRegistry,
) -> anyhow::Result<Vec<tribo::study::MassResponse>> {
    let (rig, sets_loaded) = study_inputs(a.rig.clone(), &a.sets, a.lawsets.clone())?;
    let scale_list = a.scales.clone().unwrap_or_else(|| vec![a.scale]);
    let fedem = tribo::study::fedem_rod_change();
    let body = tribo::study::ScaledBody::from(a.body);
    let fedem = (body == tribo::study::ScaledBody::Rod).then_some(fedem.as_slice());
    Ok(tribo::study::mass_response(
        &rig,
        &sets_loaded,
        body,
        &scale_list,
        registry,
        a.steady,
        fedem,
    )?)
}

/// `tribo mass-response`: the torque and friction change for a scaled body, per law set;
/// mass_response.json (and a plot for a sweep of scales) in the output directory.
fn cmd_mass_response(g: &Globals, a: MassResponseArgs) -> anyhow::Result<()> {
    let mut out_text = String::new();
    let specs = lawset_specs(&a.lawsets);
    let (rig, sets_loaded) = study_inputs(a.rig.clone(), &a.sets, specs.clone())?;
    tribo::study::check_unique_names(&sets_loaded)?;
    let scale_list = a.scales.clone().unwrap_or_else(|| vec![a.scale]);
    if let Some(bad) = scale_list.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
        anyhow::bail!("--scale/--scales: every scale factor must be positive, got {bad}");
    }
    // Once, here, before any worker: a scale the rig cannot take fails the command.
    tribo::study::check_scales(&rig, a.body.into(), &scale_list)?;
    tribo::output::check_result_dir(&a.out, "--out")?;
    let progress = Progress::start("mass response", None, g.quiet);
    let sources: Vec<SetSource> = specs
        .iter()
        .map(|l| SetSource {
            rig: a.rig.clone(),
            sets: a.sets.clone(),
            lawset: l.clone(),
            laws: Vec::new(),
            added_as: None,
        })
        .collect();
    let (result, failed) = if a.isolation.in_process {
        guard::watch(a.isolation.limits()?);
        let registry = g.registry()?;
        check_sources(&sources, &registry)?;
        (mass_study(&a, &registry)?, Vec::new())
    } else {
        let jobs = specs
            .iter()
            .map(|l| {
                WorkerJob::MassResponse(MassResponseArgs {
                    lawsets: vec![l.clone()],
                    ..a.clone()
                })
            })
            .collect();
        let labels: Vec<String> = sets_loaded.iter().map(|l| set_label(l.name())).collect();
        let results = g.run_isolated(sources, jobs, &labels, a.isolation.limits()?)?;
        let (parts, failed) = split_replies(&sets_loaded, results, |o| match o {
            WorkerOutput::MassResponse(m) => Some(m),
            _ => None,
        })?;
        let result: Vec<_> = parts.into_iter().flatten().collect();
        if result.is_empty() {
            failures_error(&failed, specs.len(), None)?;
        }
        (result, failed)
    };
    drop(progress);
    let out = &a.out;
    let files = tribo::results::write_mass_response(&result, out, a.scales.is_some())
        .with_context(|| format!("writing results into {}", out.display()))?;
    if a.json {
        writeln!(out_text, "{}", serde_json::to_string_pretty(&result)?)?;
    } else {
        write!(out_text, "{}", tribo::report::mass_text(&result))?;
        write!(out_text, "{}", wrote_into(out, &files))?;
    }
    emit(&out_text)?;
    failures_error(&failed, specs.len(), Some(out))?;
    planted_in_process(a.isolation.in_process, out)
}

/// `fit` in this process: the report and the calibrated law set as TOML.
fn fit_study(
    a: &FitArgs,
    registry: &LawRegistry,
) -> anyhow::Result<(tribo::fit::FitResult, String)> {
    let rig_path = a
        .rig
        .clone()
        .unwrap_or_else(|| PathBuf::from(tribo::bundled::DEFAULT_RIG));
    let rig = tribo::rig::load_rig(&rig_path, &a.sets)?;
    let ls = tribo::lawset::LawSet::load(&a.lawset)?;
    let runs = read_data_runs(&fit_data(a, &rig)?)?;
    let validate = read_data_runs(&a.validate)?;
    let free = ls.free_params(registry, a.params.as_deref())?;
    let options = tribo::fit::FitOptions {
        starts: a.starts as usize,
        cross_validate: !a.no_cv,
        validate,
        data_for_any_rig: a.data_for_any_rig,
    };
    let (result, fitted) = tribo::fit::fit(&rig, &ls, &free, &runs, registry, &options)?;
    let header = tribo::fit::calibrated_header(&rig, &result, runs.len());
    let text = fitted
        .to_toml(&header)
        .context("serialising the calibrated law set")?;
    Ok((result, text))
}

/// The data a fit uses: those given, or the rig's bundled measurements.
fn fit_data(a: &FitArgs, rig: &tribo::rig::Rig) -> anyhow::Result<Vec<String>> {
    if a.data.is_empty() {
        Ok(vec![data_arg(None, rig)?])
    } else {
        Ok(a.data.clone())
    }
}

/// The data a study on `rig` compares against: `given`, or the rig's own bundled measurements
/// ([`tribo::study::default_data`]).
fn data_arg(given: Option<&str>, rig: &tribo::rig::Rig) -> anyhow::Result<String> {
    match given {
        Some(d) => Ok(d.to_string()),
        None => Ok(tribo::study::default_data(rig)?.to_string()),
    }
}

/// `tribo fit`: calibrate a law set's free parameters; the report or JSON on stdout, the
/// calibrated law set written as TOML.
fn cmd_fit(g: &Globals, a: FitArgs) -> anyhow::Result<()> {
    let mut out_text = String::new();
    // Every input is read and checked before anything runs.
    let rig_path = a
        .rig
        .clone()
        .unwrap_or_else(|| PathBuf::from(tribo::bundled::DEFAULT_RIG));
    let rig = tribo::rig::load_rig(&rig_path, &a.sets)?;
    let ls = tribo::lawset::LawSet::load(&a.lawset)?;
    // Data measured on another rig, or whose cycle the rig cannot run, fail here, before the
    // worker starts.
    for d in read_data_runs(&fit_data(&a, &rig)?)?
        .iter()
        .chain(&read_data_runs(&a.validate)?)
    {
        tribo::study::check_data_rig(&rig, d, a.data_for_any_rig)?;
        tribo::study::check_data(&rig, d)?;
    }
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{}-fitted.toml", ls.name())));
    tribo::output::check_result_file(&out)?;
    let progress = Progress::start("fitting", None, g.quiet);
    let (result, text) = if a.isolation.in_process {
        guard::watch(a.isolation.limits()?);
        fit_study(&a, &g.registry()?)?
    } else {
        let label = set_label(ls.name());
        g.in_worker(
            a.isolation.limits()?,
            &WorkerJob::Fit(a.clone()),
            &format!("law set `{}`", ls.name()),
            &mut |e| isolate::show_event(&label, &e),
            |o| match o {
                WorkerOutput::Fit(result, text) => Some((*result, text)),
                _ => None,
            },
        )?
    };
    drop(progress);
    tribo::output::write_atomic(&out, text.as_bytes())
        .with_context(|| format!("writing {}", out.display()))?;
    if a.json {
        writeln!(out_text, "{}", serde_json::to_string_pretty(&result)?)?;
    } else {
        write!(out_text, "{}", tribo::report::fit_text(&result))?;
        writeln!(
            out_text,
            "wrote the calibrated law set to {}",
            out.display()
        )?;
    }
    emit(&out_text)
}

/// `sweep` for the law sets of `a`, in this process (`--oil` already in `sets`).
fn sweep_study(
    a: &SweepArgs,
    sets: &[String],
    registry: &LawRegistry,
    progress: Option<&tribo::progress::Position>,
) -> anyhow::Result<tribo::study::Sweep> {
    let temps_c = tribo::study::parse_list("--temps", &a.temps)?;
    let (rig, mut sets_loaded) = study_inputs(a.rig.clone(), sets, a.lawsets.clone())?;
    let speeds_rpm = sweep_speeds(a.speeds.as_deref(), &rig)?;
    for ls in &mut sets_loaded {
        ls.add_law_args(&a.laws)?;
    }
    Ok(tribo::study::sweep(
        &rig,
        &sets_loaded,
        &temps_c,
        &speeds_rpm,
        registry,
        progress,
    )?)
}

/// The speeds a sweep runs: `--speeds`, or the plateau speeds of the rig's own cycle.
fn sweep_speeds(given: Option<&str>, rig: &tribo::rig::Rig) -> anyhow::Result<Vec<f64>> {
    match given {
        Some(text) => Ok(tribo::study::parse_list("--speeds", text)?),
        None => Ok(tribo::study::plateau_speeds(rig)),
    }
}

/// `tribo sweep`: torque over oil temperature and speed per law set; tables or JSON on stdout,
/// sweep.csv, sweep.json and plots in the output directory.
fn cmd_sweep(g: &Globals, a: SweepArgs) -> anyhow::Result<()> {
    let mut out_text = String::new();
    // Inputs are checked before anything is loaded or run.
    let temps_c = tribo::study::parse_list("--temps", &a.temps)?;
    let sets = with_oil_file(a.oil.as_deref(), a.sets.clone())?;
    let specs = lawset_specs(&a.lawsets);
    let (rig, mut sets_loaded) = study_inputs(a.rig.clone(), &sets, specs.clone())?;
    let speeds_rpm = sweep_speeds(a.speeds.as_deref(), &rig)?;
    tribo::study::check_speeds_for_rig(&rig, &speeds_rpm, "--speeds")?;
    for ls in &mut sets_loaded {
        ls.add_law_args(&a.laws)?;
    }
    tribo::study::check_unique_names(&sets_loaded)?;
    // Once, here, before any worker: a speed the rig cannot run fails the command, not each set.
    tribo::study::check_sweep(&rig, &sets_loaded, &temps_c, &speeds_rpm)?;
    tribo::output::check_result_dir(&a.out, "--out")?;
    let total = (sets_loaded.len() * temps_c.len()) as u64;
    let sources: Vec<SetSource> = specs
        .iter()
        .map(|l| SetSource {
            rig: a.rig.clone(),
            sets: sets.clone(),
            lawset: l.clone(),
            laws: a.laws.clone(),
            added_as: None,
        })
        .collect();
    let result = if a.isolation.in_process {
        guard::watch(a.isolation.limits()?);
        let registry = g.registry()?;
        check_sources(&sources, &registry)?;
        let progress = Progress::start("temperature sweep", Some(total), g.quiet);
        let r = sweep_study(&a, &sets, &registry, Some(&progress.position()))?;
        drop(progress);
        r
    } else {
        let progress = Progress::start("temperature sweep", None, g.quiet);
        // The worker gets the --oil file already turned into --set overrides.
        let jobs = specs
            .iter()
            .map(|l| {
                WorkerJob::Sweep(SweepArgs {
                    lawsets: vec![l.clone()],
                    sets: sets.clone(),
                    oil: None,
                    ..a.clone()
                })
            })
            .collect();
        let labels: Vec<String> = sets_loaded.iter().map(|l| set_label(l.name())).collect();
        let results = g.run_isolated(sources, jobs, &labels, a.isolation.limits()?)?;
        drop(progress);
        merge_sweeps(&sets_loaded, results)?
    };
    let out = &a.out;
    let files = tribo::results::write_sweep(&result, out)
        .with_context(|| format!("writing results into {}", out.display()))?;
    if a.json {
        writeln!(out_text, "{}", serde_json::to_string_pretty(&result)?)?;
    } else {
        write!(out_text, "{}", tribo::report::sweep_text(&result))?;
        write!(out_text, "{}", tribo::beside::sweep_text(&result))?;
        write!(out_text, "\n{}", wrote_into(out, &files))?;
    }
    emit(&out_text)?;
    failures_error(&result.failed, specs.len(), Some(out))?;
    planted_in_process(a.isolation.in_process, out)
}

/// One sweep from the one-set sweeps of the workers, failed sets listed.
fn merge_sweeps(
    lawsets: &[tribo::lawset::LawSet],
    results: Vec<Result<WorkerOutput, WorkerFailure>>,
) -> anyhow::Result<tribo::study::Sweep> {
    let (parts, failed) = split_replies(lawsets, results, |o| match o {
        WorkerOutput::Sweep(w) => Some(*w),
        _ => None,
    })?;
    let mut parts = parts.into_iter();
    let Some(mut sweep) = parts.next() else {
        failures_error(&failed, lawsets.len(), None)?;
        anyhow::bail!("no law set to sweep");
    };
    sweep.sets.extend(parts.flat_map(|w| w.sets));
    sweep.failed = failed;
    Ok(sweep)
}

/// The hidden worker subcommand: answer the parent's jobs on the channel it set up, then end.
/// Standard output stays on `/dev/null`, where the parent put it: a law's printing goes
/// nowhere.
fn cmd_worker(g: &Globals) -> ! {
    isolate::serve(|job: WorkerJob, session: &isolate::Session| {
        work(g, job, session).map_err(|e| format!("{e:#}"))
    })
}

/// One job in a worker process.
fn work(g: &Globals, job: WorkerJob, session: &isolate::Session) -> anyhow::Result<WorkerOutput> {
    test_panic_hook("worker");
    // A study's result folder is watched while its laws run: tribo writes there only after
    // every set has finished, so what this process makes there is a law's doing.
    let watch = match &job {
        WorkerJob::Compare(a) => Some(&a.out),
        WorkerJob::MassResponse(a) => Some(&a.out),
        WorkerJob::Sweep(a) => Some(&a.out),
        _ => None,
    }
    .and_then(|out| planted_watch(out));
    let output = work_on(g, job, session)?;
    if let Some(w) = watch {
        planted_check(&w)?;
    }
    Ok(output)
}

/// A watch on the result folder `out` for entries this worker makes (Linux).
#[cfg(target_os = "linux")]
fn planted_watch(out: &std::path::Path) -> Option<isolate::planted::Planted> {
    isolate::planted::Planted::watch(out)
}

#[cfg(not(target_os = "linux"))]
fn planted_watch(_out: &std::path::Path) -> Option<std::convert::Infallible> {
    None
}

/// The job's failure if this worker made entries in the watched result folder: the entries,
/// the folder and the laws that ran (one of them did it).
#[cfg(target_os = "linux")]
fn planted_check(w: &isolate::planted::Planted) -> anyhow::Result<()> {
    let made = w.made_here();
    if made.is_empty() {
        return Ok(());
    }
    // Told to the parent too, which watches the folder for the processes laws start.
    for n in &made {
        isolate::guard::marker("planted", n);
    }
    let laws = laws_loaded_here();
    let shown: Vec<String> = made.iter().take(5).map(|n| format!("`{n}`")).collect();
    anyhow::bail!(
        "a law of this set wrote {}{} into the result folder {} while it ran (tribo writes there only after every law has finished; what it wrote is removed); the laws that ran: {}",
        shown.join(", "),
        if made.len() > 5 { format!(" and {} more", made.len() - 5) } else { String::new() },
        w.dir().display(),
        if laws.is_empty() { "none registered".to_string() } else { laws.join(", ") }
    )
}

/// The laws this process has loaded, by name, file and joint.
fn laws_loaded_here() -> Vec<&'static str> {
    let names: Vec<&str> = (1..)
        .map_while(tribo_plugin_api::loader::inflight::name)
        .filter(|n| n.starts_with("law `"))
        .collect();
    // A law bound to a joint is registered twice (alone and at its joint): the joints say more.
    let at_joints: Vec<&str> = names
        .iter()
        .copied()
        .filter(|n| n.contains(" at joint `"))
        .collect();
    if at_joints.is_empty() {
        names
    } else {
        at_joints
    }
}

/// With `--in-process`, what appeared in the result folder `out` while the laws ran (a law,
/// or a process it started, wrote it) fails the command once the results are written: every
/// set ran in this process, so none can be singled out, and the results stay (the entries are
/// removed). Without it the workers' watch fails the set that did it.
fn planted_in_process(in_process: bool, out: &std::path::Path) -> anyhow::Result<()> {
    let planted = tribo::output::take_planted(out);
    if !in_process || planted.is_empty() {
        return Ok(());
    }
    let shown: Vec<String> = planted.iter().take(5).map(|n| format!("`{n}`")).collect();
    let laws = laws_loaded_here();
    anyhow::bail!(
        "a law, or a process it started, wrote {} into the result folder {} while the laws ran (removed; the results were written); with --in-process every law set runs in this process, so tribo cannot tell whose law it was: run without --in-process to have that set named and failed; the laws loaded: {}",
        shown.join(", "),
        out.display(),
        if laws.is_empty() { "none registered".to_string() } else { laws.join(", ") }
    )
}

#[cfg(not(target_os = "linux"))]
fn planted_check(w: &std::convert::Infallible) -> anyhow::Result<()> {
    match *w {}
}

/// The job itself, in this worker.
fn work_on(
    g: &Globals,
    job: WorkerJob,
    session: &isolate::Session,
) -> anyhow::Result<WorkerOutput> {
    let registry = g.registry()?;
    Ok(match job {
        WorkerJob::Check(sources) => {
            check_sources(&sources, &registry)?;
            WorkerOutput::Checked
        }
        WorkerJob::Compare(args) => {
            WorkerOutput::Compare(Box::new(compare_study(&args, &registry)?))
        }
        WorkerJob::MassResponse(args) => WorkerOutput::MassResponse(mass_study(&args, &registry)?),
        WorkerJob::Sweep(args) => {
            let sets = args.sets.clone();
            WorkerOutput::Sweep(Box::new(sweep_study(&args, &sets, &registry, None)?))
        }
        WorkerJob::Fit(args) => {
            let (result, text) = fit_study(&args, &registry)?;
            WorkerOutput::Fit(Box::new(result), text)
        }
        WorkerJob::Run(job) => {
            let position = tribo::progress::Position::default();
            let mut sink = DataSink {
                session,
                buf: Vec::new(),
            };
            // The progress reporter ticks every 50 ms and stops as soon as the run ends (the
            // sender dropped), not at its next tick.
            let (finished, ended) = std::sync::mpsc::channel::<()>();
            let output = std::thread::scope(|s| {
                let position = &position;
                s.spawn(move || {
                    let tick = std::time::Duration::from_millis(50);
                    while tribo::progress::still_running(&ended, tick) {
                        session.progress(position.get());
                    }
                });
                let r = job.simulate(&registry, position.clone(), Some(&mut sink));
                drop(finished);
                r
            })?;
            use std::io::Write as _;
            sink.flush().context("sending the time series")?;
            WorkerOutput::Run(Box::new(output))
        }
        WorkerJob::CheckLaw(job) => WorkerOutput::CheckLaw(job.check(&registry)?),
        WorkerJob::PlotLaw(job) => WorkerOutput::PlotLaw(Box::new(job.sample(&registry)?)),
        WorkerJob::Laws(job) => WorkerOutput::Laws(laws::render(&registry, &job)?),
        WorkerJob::Bind(job) => {
            tribo::rig::simulation(&job.rig()?, &registry)?;
            WorkerOutput::Checked
        }
    })
}

/// Streamed output of a worker (the time series) sent to the parent in chunks.
struct DataSink<'a> {
    session: &'a isolate::Session,
    buf: Vec<u8>,
}

impl std::io::Write for DataSink<'_> {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        self.buf.extend_from_slice(bytes);
        if self.buf.len() >= 1 << 16 {
            self.flush()?;
        }
        Ok(bytes.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        if !self.buf.is_empty() {
            self.session.data(&self.buf)?;
            self.buf.clear();
        }
        Ok(())
    }
}

/// Test hook: with `TRIBO_TEST_PANIC=PLACE` (`main`, `worker`), tribo panics there, so the tests
/// can check a bug in tribo is reported as one (never as a law's `exit()`). Unset in normal use.
fn test_panic_hook(place: &str) {
    if std::env::var_os("TRIBO_TEST_PANIC").is_some_and(|p| p == place) {
        panic!("TRIBO_TEST_PANIC={place}");
    }
}

/// `tribo fmu export`: the rig with its laws (checked by binding them) written as an FMU.
fn cmd_fmu_export(g: &Globals, a: FmuExportArgs) -> anyhow::Result<()> {
    let rig = a.rig.load()?;
    // The laws are bound in a worker first: a library whose loading or binding ends, crashes
    // or hangs the process fails the export naming it, before this process opens it.
    let job = RunJob {
        rig: a.rig.rig.clone(),
        sets: with_oil_file(a.rig.oil.as_deref(), a.rig.sets.clone())?,
        lawset: a.rig.lawset.clone(),
        laws: a.rig.laws.clone(),
        steady: false,
        timeseries: false,
        crank_angle_deg: None,
        require_laws: false,
    };
    g.in_worker(
        isolate::Limits::default(),
        &WorkerJob::Bind(job),
        "checking the rig's laws in a worker process",
        // This process prints the registry's warnings itself, below.
        &mut |e| match e {
            Event::Stderr(line) if line.starts_with("warning:") => {}
            other => isolate::show_event("", &other),
        },
        |o| matches!(o, WorkerOutput::Checked).then_some(()),
    )?;
    let registry = g.registry()?;
    // Every law bound once here, so a bad law or parameter is reported where it was written.
    tribo::rig::simulation(&rig, &registry)?;
    let exe = std::env::current_exe()
        .context("finding the tribo executable to ship as the FMU's worker")?;
    let library = exe
        .parent()
        .map(|d| d.join(format!("lib{}.so", tribo_fmu::interface::MODEL_IDENTIFIER)))
        .filter(|p| p.is_file())
        .with_context(|| format!("the FMU library libtribo_fmu.so is not next to {}; build it with `cargo build --release -p tribo-fmu`", exe.display()))?;
    let drive = match a.input.as_str() {
        "drive-torque" => tribo_fmu::interface::DriveMode::Torque,
        _ => tribo_fmu::interface::DriveMode::Speed,
    };
    let iface = tribo_fmu::export::export(
        &tribo_fmu::export::Export {
            model: rig.model(),
            registry: &registry,
            drive,
            worker_exe: &exe,
            fmu_library: &library,
            tribo_version: env!("CARGO_PKG_VERSION"),
        },
        &a.out,
    )
    .with_context(|| format!("exporting the FMU {}", a.out.display()))?;
    emit(&tribo_fmu::export::summary(&iface, &a.out))
}

/// `tribo __fmu-worker RESOURCES`: one FMU instance's worker, answering on standard output
/// (the real one: whatever a law prints goes to standard error).
fn cmd_fmu_worker(a: &FmuWorkerArgs) -> anyhow::Result<()> {
    // The law calls are marked on the page the FMU shares, before any law is loaded.
    #[cfg(unix)]
    isolate::page::adopt();
    struct Results;
    impl std::io::Write for Results {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            match RESULTS_OUT.get() {
                Some(out) => out.lock().unwrap_or_else(|p| p.into_inner()).write(buf),
                None => std::io::stdout().write(buf),
            }
        }
        fn flush(&mut self) -> std::io::Result<()> {
            match RESULTS_OUT.get() {
                Some(out) => out.lock().unwrap_or_else(|p| p.into_inner()).flush(),
                None => std::io::stdout().flush(),
            }
        }
    }
    tribo_fmu::worker::serve(&a.resources, std::io::stdin().lock(), Results)?;
    Ok(())
}

/// A failure already reported elsewhere (a worker's reply): exit status 1, no message.
#[derive(Debug, thiserror::Error)]
#[error("failed")]
struct QuietFailure;

/// `tribo new-law`: generate a law crate and say how to test and build it.
fn cmd_new_law(a: NewLawArgs) -> anyhow::Result<()> {
    let mut out_text = String::new();
    let cwd = std::env::current_dir().context("reading the current directory")?;
    // The Makefiles of C, C++ and Fortran laws run this tribo for `make check`.
    let exe = std::env::current_exe().unwrap_or_else(|_| PathBuf::from("tribo"));
    let s = scaffold::new_law(&a.name, a.lang, a.dir.as_deref(), &cwd, &exe)?;
    match &s.crate_name {
        Some(krate) => writeln!(out_text, "created {krate} in {}", s.dir.display())?,
        None => writeln!(
            out_text,
            "created law `{}` ({}) in {}",
            s.name,
            s.lang,
            s.dir.display()
        )?,
    }
    for step in s.next_steps() {
        writeln!(out_text, "  {step}")?;
    }
    emit(&out_text)
}

/// A `tribo check-law`: the law (a file or a name), its parameters, the options.
#[derive(Serialize, Deserialize)]
struct CheckJob {
    law: String,
    params: toml::Table,
    active: Option<String>,
    json: bool,
}

/// A law's conformance report, rendered, and the checks it failed.
#[derive(Serialize, Deserialize)]
struct CheckOutput {
    law: String,
    text: String,
    failed: Vec<String>,
}

/// `check-law`'s table with every line within the report's width: the heading line broken
/// at spaces, each check's detail wrapped under its own column (the first 30 characters of a
/// row: name and result).
fn wrap_check_table(table: &str) -> String {
    const DETAIL: usize = 30;
    let width = tribo::report::MAX_COLUMNS;
    let (head, rows) = table.split_once('\n').unwrap_or((table, ""));
    let mut out = tribo::report::wrap(head, width, "    ");
    let indent = " ".repeat(DETAIL);
    for row in rows.lines() {
        match row.split_at_checked(DETAIL) {
            Some((check, detail)) if row.chars().count() > width => {
                let detail = tribo::report::wrap(detail, width - DETAIL, "");
                for (k, line) in detail.lines().enumerate() {
                    out.push_str(if k == 0 { check } else { &indent });
                    out.push_str(line);
                    out.push('\n');
                }
            }
            _ => {
                out.push_str(row);
                out.push('\n');
            }
        }
    }
    out
}

impl CheckJob {
    /// Open the law and run the conformance checks on it.
    fn check(self, registry: &LawRegistry) -> anyhow::Result<CheckOutput> {
        use tribo_plugin_api::conformance;
        let lib = tribo::check::open_law(registry, &self.law)?;
        let options = conformance::Options {
            params: self.params,
            active: self.active,
        };
        let report = conformance::check_with(&lib, &options);
        let text = if self.json {
            format!("{}\n", serde_json::to_string_pretty(&report)?)
        } else {
            wrap_check_table(&report.to_table())
        };
        Ok(CheckOutput {
            law: report.law.clone(),
            text,
            failed: report
                .failed()
                .iter()
                .map(|c| c.as_str().to_string())
                .collect(),
        })
    }
}

/// `tribo check-law`: the conformance checks on one law (in a worker process unless
/// `--in-process`), as a table or JSON; exit 1 naming the failed checks.
fn cmd_check_law(g: &Globals, a: CheckLawArgs) -> anyhow::Result<()> {
    let job = CheckJob {
        params: tribo::check::read_params(a.params.as_deref())?,
        law: a.law.clone(),
        active: a.active,
        json: a.json,
    };
    let limits = a.isolation.limits()?;
    let report = if a.isolation.in_process {
        guard::watch(limits);
        job.check(&g.registry()?)?
    } else {
        g.in_worker(
            limits,
            &WorkerJob::CheckLaw(job),
            &format!("checking `{}`", a.law),
            &mut |e| isolate::show_event("", &e),
            |o| match o {
                WorkerOutput::CheckLaw(c) => Some(c),
                _ => None,
            },
        )?
    };
    emit(&report.text)?;
    if report.failed.is_empty() {
        Ok(())
    } else {
        anyhow::bail!(
            "law `{}` failed {} check{}: {}",
            report.law,
            report.failed.len(),
            if report.failed.len() == 1 { "" } else { "s" },
            report.failed.join(", ")
        )
    }
}

/// A `tribo plot-law`: the law (a file or a name), its parameters, the joint.
#[derive(Serialize, Deserialize)]
struct PlotJob {
    law: String,
    params: toml::Table,
    joint: String,
}

impl PlotJob {
    /// Open the law and sample its curves.
    fn sample(self, registry: &LawRegistry) -> anyhow::Result<tribo::check::LawCurves> {
        let lib = tribo::check::open_law(registry, &self.law)?;
        Ok(tribo::check::sample_law(&lib, &self.params, &self.joint)?)
    }
}

/// `tribo plot-law`: a law's force-velocity curves (sampled in a worker process unless
/// `--in-process`) as an SVG file.
fn cmd_plot_law(g: &Globals, a: PlotLawArgs) -> anyhow::Result<()> {
    let job = PlotJob {
        params: tribo::check::read_params(a.params.as_deref())?,
        law: a.law.clone(),
        joint: a.joint,
    };
    if let Some(out) = &a.out {
        tribo::output::check_result_file(out)?;
    }
    let limits = a.isolation.limits()?;
    let curves = if a.isolation.in_process {
        guard::watch(limits);
        job.sample(&g.registry()?)?
    } else {
        g.in_worker(
            limits,
            &WorkerJob::PlotLaw(job),
            &format!("plotting `{}`", a.law),
            &mut |e| isolate::show_event("", &e),
            |o| match o {
                WorkerOutput::PlotLaw(c) => Some(*c),
                _ => None,
            },
        )?
    };
    let out = a.out.unwrap_or_else(|| {
        PathBuf::from(format!("plot_{}.svg", tribo::plots::file_stem(&curves.law)))
    });
    tribo::output::check_result_file(&out)?;
    tribo::plots::write_law_plot(&curves, &out)?;
    emit(&format!("wrote {}\n", out.display()))
}

/// Data files (CSV) or bundled data names, read in order.
fn read_data_runs(names: &[String]) -> anyhow::Result<Vec<tribo::study::DataRun>> {
    Ok(names
        .iter()
        .map(|n| tribo::study::DataRun::read(n))
        .collect::<Result<Vec<_>, _>>()?)
}

/// Standard output could not be written (a closed pipe, a full disk). Kept apart from other
/// I/O errors so `main` can end quietly on a reader that went away. The I/O error is part of
/// the message and not also its source, which the error chain would print a second time.
#[derive(Debug, thiserror::Error)]
#[error("cannot write the results to standard output: {0}")]
struct StdoutError(std::io::Error);

/// Where results go: the real standard output, taken at start-up (standard output itself then
/// points at standard error, so text a law prints cannot mix with the results).
static RESULTS_OUT: std::sync::OnceLock<std::sync::Mutex<std::fs::File>> =
    std::sync::OnceLock::new();

/// Write a command's results to standard output and flush them; failure is an error, never a
/// panic (unlike `print!`).
fn emit(text: &str) -> anyhow::Result<()> {
    use std::io::Write as _;
    if let Some(out) = RESULTS_OUT.get() {
        let mut out = out.lock().unwrap_or_else(|p| p.into_inner());
        out.write_all(text.as_bytes())
            .and_then(|()| out.flush())
            .map_err(StdoutError)?;
        return Ok(());
    }
    let mut stdout = std::io::stdout().lock();
    stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush())
        .map_err(StdoutError)?;
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // From here on an exit() that tribo did not ask for is a law's, and fails the run.
    guard::install();
    if matches!(cli.command, Command::Worker) {
        cmd_worker(&Globals {
            plugins: cli.plugins,
            quiet: true,
        });
    }
    // Ctrl-C or a kill ends the workers' process groups too (what a law started in them).
    isolate::handle_termination();
    test_panic_hook("main");
    if let Some(out) = guard::take_stdout() {
        let _ = RESULTS_OUT.set(std::sync::Mutex::new(out));
    }
    let result = run(cli);
    guard::allow_exit();
    let code = match result {
        Ok(()) => 0,
        Err(e) if e.downcast_ref::<QuietFailure>().is_some() => 1,
        // The reader of our output went away (`tribo laws | head -1`): nothing to tell it, and
        // the results were not delivered, so exit 1 without a message (docs/reliability.md).
        Err(e)
            if e.downcast_ref::<StdoutError>()
                .is_some_and(|s| s.0.kind() == std::io::ErrorKind::BrokenPipe) =>
        {
            1
        }
        Err(e) => {
            use std::io::Write as _;
            // Ignored: if standard error is gone too there is nowhere left to report to.
            let _ = writeln!(std::io::stderr(), "error: {e:#}");
            1
        }
    };
    // No destructor or atexit handler of a law loaded in process runs after this: one that
    // calls _exit(0) would turn a failure into a success.
    guard::end(code)
}
