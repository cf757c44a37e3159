//! The `tribo` command: a thin layer over the host library that parses arguments, runs one
//! command and reports errors with their context.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, Parser, Subcommand};
use tribo::progress::Progress;
use tribo::{laws, scaffold};
use tribo_plugin_api::loader::{discover, LawRegistry};

/// Tribo: a virtual engine-friction test bench with friction and damping laws as plugins.
#[derive(Parser)]
#[command(version, about, long_about = None)]
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
    /// Calibrate a law set's free parameters to measured torque (least squares, steady state).
    Fit(FitArgs),
    /// Motoring torque over oil temperature and engine speed for each law set (steady state):
    /// a table per law set, sweep.csv, sweep.json and one plot per law set.
    Sweep(SweepArgs),
    /// Generate a new law plugin crate with a documented law, parameters and unit tests.
    NewLaw(NewLawArgs),
}

/// The arguments of `tribo laws`.
#[derive(Args)]
struct LawsArgs {
    /// Machine-readable JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// The arguments of `tribo run`.
#[derive(Args)]
struct RunArgs {
    /// Rig file (TOML).
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
    /// Compute each plateau's periodic steady state directly instead of the whole cycle.
    #[arg(long)]
    steady: bool,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Also write plateaus.csv and joints.csv into this directory.
    #[arg(long, value_name = "DIR")]
    csv: Option<PathBuf>,
    /// Stream the time history (one line per step) to this CSV file.
    #[arg(long, value_name = "FILE")]
    timeseries: Option<PathBuf>,
}

/// The arguments of `tribo compare`.
#[derive(Args)]
struct CompareArgs {
    /// Rig file or bundled rig name (default: the bundled CRF 250 R rig).
    rig: Option<PathBuf>,
    /// Law set (bundled name or file); repeat to compare several (default: fedem-baseline
    /// and stribeck-duty).
    #[arg(long = "lawset")]
    lawsets: Vec<String>,
    /// Attach a law to every law set: JOINT=LAW[:PARAMS.toml] (added to the set's laws there).
    #[arg(long = "law", value_name = "JOINT=LAW[:PARAMS_TOML_FILE]")]
    laws: Vec<String>,
    /// Measured data, CSV speed_rpm,torque_nm,oil_temp_c (default: the thesis's table 10.4).
    #[arg(long)]
    data: Option<String>,
    /// Override rig values, as for `run`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Output directory for comparison.csv, comparison.json and the plots.
    #[arg(long, default_value = "tribo-compare")]
    out: PathBuf,
    /// Steady state at each speed instead of the full test cycle.
    #[arg(long)]
    steady: bool,
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
}

/// The arguments of `tribo mass-response`.
#[derive(Args)]
struct MassResponseArgs {
    /// Rig file or bundled rig name (default: the bundled CRF 250 R rig).
    rig: Option<PathBuf>,
    /// Body to scale.
    #[arg(long, value_enum, default_value = "rod")]
    body: BodyArg,
    /// Mass (and inertia) scale factor.
    #[arg(long, default_value_t = 0.6)]
    scale: f64,
    /// A sweep of scale factors instead (e.g. 0.5,0.6,...,1.1); writes a plot.
    #[arg(long, value_delimiter = ',')]
    scales: Option<Vec<f64>>,
    /// Law set (bundled name or file); repeat for several (default: fedem-baseline and
    /// stribeck-duty).
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
}

/// The arguments of `tribo fit`.
#[derive(Args)]
struct FitArgs {
    /// Rig file or bundled rig name (default: the bundled CRF 250 R rig).
    rig: Option<PathBuf>,
    /// Law set to calibrate (bundled name or file).
    #[arg(long)]
    lawset: String,
    /// Parameters to fit, JOINT.LAW.PARAM,... (default: those the law set marks free).
    #[arg(long, value_delimiter = ',')]
    params: Option<Vec<String>>,
    /// Measured data, CSV speed_rpm,torque_nm,oil_temp_c (default: the thesis's table 10.4);
    /// repeat for several runs: one parameter set is fitted to all, each point at its own
    /// oil temperature.
    #[arg(long = "data", value_name = "FILE")]
    data: Vec<String>,
    /// Data never used in fitting, scored with the fitted values; repeatable.
    #[arg(long = "validate", value_name = "FILE")]
    validate: Vec<String>,
    /// Start points: the law set's values, then quasi-random points over the bounds; the
    /// best result is kept and the spread of the others reported.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64))]
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
}

/// The arguments of `tribo sweep`.
#[derive(Args)]
struct SweepArgs {
    /// Rig file or bundled rig name (default: the bundled CRF 250 R rig).
    rig: Option<PathBuf>,
    /// Law set (bundled name or file); repeat for several (default: fedem-baseline and
    /// stribeck-duty).
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
    /// Engine speeds, rpm, comma-separated.
    #[arg(
        long,
        value_name = "RPM,RPM,...",
        default_value = "3000,4000,5000,6000,7000,8000,9000",
        allow_hyphen_values = true
    )]
    speeds: String,
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
}

/// The arguments of `tribo new-law`.
#[derive(Args)]
struct NewLawArgs {
    /// Law name: lowercase letters, digits and hyphens (e.g. `my-law`).
    name: String,
    /// Directory to create the crate in (default: the workspace's plugins/).
    #[arg(long)]
    dir: Option<PathBuf>,
}

/// The body a mass study scales, as the command line spells it.
#[derive(Clone, Copy, clap::ValueEnum)]
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

/// The options every command shares.
struct Globals {
    /// Extra plugin libraries or directories (`--plugin`).
    plugins: Vec<PathBuf>,
    /// No progress display (`--quiet`).
    quiet: bool,
}

impl Globals {
    /// Every law plugin found (`--plugin`, `TRIBO_PLUGIN_PATH`, the executable's directory).
    fn registry(&self) -> anyhow::Result<LawRegistry> {
        discover(&self.plugins).context("loading law plugins")
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
        Command::Sweep(a) => cmd_sweep(&g, a),
        Command::NewLaw(a) => cmd_new_law(a),
    }
}

/// `tribo laws`: the laws found, as a table or JSON.
fn cmd_laws(g: &Globals, a: LawsArgs) -> anyhow::Result<()> {
    let mut out_text = String::new();
    let registry = g.registry()?;
    if a.json {
        writeln!(
            out_text,
            "{}",
            serde_json::to_string_pretty(&laws::to_json(&registry))?
        )?;
    } else {
        write!(out_text, "{}", laws::to_text(&registry))?;
    }
    emit(&out_text)
}

/// `tribo run`: one rig through its cycle (or steady state), reported as a table or JSON, with
/// optional CSV files and time series.
fn cmd_run(g: &Globals, a: RunArgs) -> anyhow::Result<()> {
    let mut out_text = String::new();
    let RunArgs {
        rig,
        laws: law_args,
        sets,
        oil,
        lawset,
        steady,
        json,
        csv,
        timeseries,
    } = a;
    let sets = with_oil_file(oil.as_deref(), sets)?;
    let mut rig = tribo::rig::load_rig(&rig, &sets)?;
    if let Some(ls) = lawset {
        tribo::lawset::LawSet::load(&ls)?.apply(&mut rig);
    }
    tribo::rig::attach_laws(&mut rig, &law_args)?;
    let registry = g.registry()?;
    let mut sim = tribo::rig::simulation(&rig, &registry)?;
    let progress = Progress::start("simulating the test cycle", Some(1000), g.quiet);
    sim.report_progress(progress.position());
    let result = match &timeseries {
        _ if steady => sim.run_steady()?,
        Some(path) => {
            let file = tribo::output::AtomicFile::create(path)
                .with_context(|| format!("creating {}", path.display()))?;
            let mut series = tribo::timeseries::TimeSeries::new(file);
            let r = sim.run_with(&mut series)?;
            series
                .into_inner()
                .commit()
                .with_context(|| format!("writing {}", path.display()))?;
            r
        }
        None => sim.run()?,
    };
    drop(progress);
    if let Some(dir) = &csv {
        tribo::report::write_csv(&result, dir)
            .with_context(|| format!("writing CSV into {}", dir.display()))?;
    }
    if json {
        writeln!(out_text, "{}", serde_json::to_string_pretty(&result)?)?;
    } else {
        writeln!(out_text, "oil: {}", rig.file.oil.describe())?;
        write!(out_text, "{}", tribo::report::to_text(&result))?;
    }
    emit(&out_text)
}

/// `tribo compare`: law sets side by side against measured data; table or JSON on stdout,
/// CSV, JSON and plots in the output directory.
fn cmd_compare(g: &Globals, a: CompareArgs) -> anyhow::Result<()> {
    let mut out_text = String::new();
    let (rig, mut sets_loaded) = study_inputs(a.rig, &a.sets, a.lawsets)?;
    for ls in &mut sets_loaded {
        ls.add_law_args(&a.laws)?;
    }
    let data =
        tribo::study::DataRun::read(a.data.as_deref().unwrap_or(tribo::bundled::DEFAULT_DATA))?;
    let validate = read_data_runs(&a.validate)?;
    let registry = g.registry()?;
    let progress = Progress::start("comparing law sets", None, g.quiet);
    let options = tribo::study::CompareOptions {
        steady: a.steady,
        no_cv: a.no_cv,
        validate,
    };
    let cmp = tribo::study::compare(&rig, &sets_loaded, &data, &registry, &options)?;
    drop(progress);
    let out = &a.out;
    tribo::plots::write_comparison(&cmp, out)
        .with_context(|| format!("writing results into {}", out.display()))?;
    if a.json {
        writeln!(out_text, "{}", serde_json::to_string_pretty(&cmp)?)?;
    } else {
        write!(out_text, "{}", tribo::report::comparison_text(&cmp))?;
        writeln!(
            out_text,
            "\nwrote into {}: comparison.csv, scores.csv, validation.csv, comparison.json,\n  torque_vs_speed.svg, contributions_*.svg, piston_regimes.svg",
            out.display()
        )?;
    }
    emit(&out_text)
}

/// `tribo mass-response`: the torque and friction change for a scaled body, per law set;
/// mass_response.json (and a plot for a sweep of scales) in the output directory.
fn cmd_mass_response(g: &Globals, a: MassResponseArgs) -> anyhow::Result<()> {
    let mut out_text = String::new();
    let (rig, sets_loaded) = study_inputs(a.rig, &a.sets, a.lawsets)?;
    let scale_list = a.scales.clone().unwrap_or_else(|| vec![a.scale]);
    if let Some(bad) = scale_list.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
        anyhow::bail!("--scale/--scales: every scale factor must be positive, got {bad}");
    }
    let registry = g.registry()?;
    let fedem = tribo::study::fedem_rod_change();
    let body = tribo::study::ScaledBody::from(a.body);
    let fedem = (body == tribo::study::ScaledBody::Rod).then_some(fedem.as_slice());
    let progress = Progress::start("mass response", None, g.quiet);
    let result = tribo::study::mass_response(
        &rig,
        &sets_loaded,
        body,
        &scale_list,
        &registry,
        a.steady,
        fedem,
    )?;
    drop(progress);
    let out = &a.out;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    tribo::output::write_atomic(
        &out.join("mass_response.json"),
        serde_json::to_string_pretty(&result)?.as_bytes(),
    )?;
    if a.scales.is_some() {
        tribo::plots::write_mass_sweep(&result, &out.join("mass_sweep.svg"))?;
    }
    if a.json {
        writeln!(out_text, "{}", serde_json::to_string_pretty(&result)?)?;
    } else {
        write!(out_text, "{}", tribo::report::mass_text(&result))?;
    }
    emit(&out_text)
}

/// `tribo fit`: calibrate a law set's free parameters; the report or JSON on stdout, the
/// calibrated law set written as TOML.
fn cmd_fit(g: &Globals, a: FitArgs) -> anyhow::Result<()> {
    let mut out_text = String::new();
    let rig_path = a
        .rig
        .unwrap_or_else(|| PathBuf::from(tribo::bundled::DEFAULT_RIG));
    let rig = tribo::rig::load_rig(&rig_path, &a.sets)?;
    let ls = tribo::lawset::LawSet::load(&a.lawset)?;
    let data = if a.data.is_empty() {
        vec![tribo::bundled::DEFAULT_DATA.to_string()]
    } else {
        a.data
    };
    let runs = read_data_runs(&data)?;
    let validate = read_data_runs(&a.validate)?;
    let registry = g.registry()?;
    let free = ls.free_params(&registry, a.params.as_deref())?;
    let progress = Progress::start("fitting", None, g.quiet);
    let options = tribo::fit::FitOptions {
        starts: a.starts as usize,
        cross_validate: !a.no_cv,
        validate,
    };
    let (result, fitted) = tribo::fit::fit(&rig, &ls, &free, &runs, &registry, &options)?;
    drop(progress);
    let out = a
        .out
        .unwrap_or_else(|| PathBuf::from(format!("{}-fitted.toml", ls.name())));
    let header = format!(
        "Calibrated by `tribo fit` on rig {} against {} points in {} run(s): RMSE {:.4} N m in sample, {} N m leave-one-out.\nParameters fitted: {}",
        rig.file.name,
        result.measured_nm.len(),
        runs.len(),
        result.rmse_nm,
        result
            .scores
            .cv_rmse_nm
            .map_or("(not computed)".to_string(), |v| format!("{v:.4}")),
        result.params.join(", ")
    );
    let text = fitted
        .to_toml(&header)
        .context("serialising the calibrated law set")?;
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

/// `tribo sweep`: torque over oil temperature and speed per law set; tables or JSON on stdout,
/// sweep.csv, sweep.json and plots in the output directory.
fn cmd_sweep(g: &Globals, a: SweepArgs) -> anyhow::Result<()> {
    let mut out_text = String::new();
    // Inputs are checked before anything is loaded or run.
    let temps_c = tribo::study::parse_list("--temps", &a.temps)?;
    let speeds_rpm = tribo::study::parse_list("--speeds", &a.speeds)?;
    tribo::study::check_sweep_inputs(&temps_c, &speeds_rpm)?;
    let sets = with_oil_file(a.oil.as_deref(), a.sets)?;
    let (rig, mut sets_loaded) = study_inputs(a.rig, &sets, a.lawsets)?;
    for ls in &mut sets_loaded {
        ls.add_law_args(&a.laws)?;
    }
    let registry = g.registry()?;
    let total = (sets_loaded.len() * temps_c.len()) as u64;
    let progress = Progress::start("temperature sweep", Some(total), g.quiet);
    let result = tribo::study::sweep(
        &rig,
        &sets_loaded,
        &temps_c,
        &speeds_rpm,
        &registry,
        Some(&progress.position()),
    )?;
    drop(progress);
    let out = &a.out;
    let files = tribo::plots::write_sweep(&result, out)
        .with_context(|| format!("writing results into {}", out.display()))?;
    if a.json {
        writeln!(out_text, "{}", serde_json::to_string_pretty(&result)?)?;
    } else {
        write!(out_text, "{}", tribo::report::sweep_text(&result))?;
        writeln!(out_text, "\nwrote {}/{}", out.display(), files.join(", "))?;
    }
    emit(&out_text)
}

/// `tribo new-law`: generate a law crate and say how to test and build it.
fn cmd_new_law(a: NewLawArgs) -> anyhow::Result<()> {
    let mut out_text = String::new();
    let cwd = std::env::current_dir().context("reading the current directory")?;
    let s = scaffold::new_law(&a.name, a.dir.as_deref(), &cwd)?;
    writeln!(out_text, "created {} in {}", s.crate_name, s.dir.display())?;
    writeln!(out_text, "  test:  cargo test -p {}", s.crate_name)?;
    writeln!(
        out_text,
        "  build: cargo build --release -p {}",
        s.crate_name
    )?;
    if s.workspace_member {
        writeln!(
            out_text,
            "  the library {} lands in target/release/, where tribo finds it",
            s.library_file
        )?;
    } else {
        writeln!(
            out_text,
            "  then put {} in a directory on TRIBO_PLUGIN_PATH or pass --plugin",
            s.library_file
        )?;
    }
    emit(&out_text)
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

/// Write a command's results to standard output and flush them; failure is an error, never a
/// panic (unlike `print!`).
fn emit(text: &str) -> anyhow::Result<()> {
    use std::io::Write as _;
    let mut stdout = std::io::stdout().lock();
    stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush())
        .map_err(StdoutError)?;
    Ok(())
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        // The reader of our output went away (`tribo laws | head -1`): nothing to tell it, and
        // the results were not delivered, so exit 1 without a message (docs/reliability.md).
        Err(e)
            if e.downcast_ref::<StdoutError>()
                .is_some_and(|s| s.0.kind() == std::io::ErrorKind::BrokenPipe) =>
        {
            ExitCode::FAILURE
        }
        Err(e) => {
            use std::io::Write as _;
            // Ignored: if standard error is gone too there is nowhere left to report to.
            let _ = writeln!(std::io::stderr(), "error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
