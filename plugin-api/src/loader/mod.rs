//! Host side: find law libraries, load them through either ABI, and hand the solver one kind of
//! handle ([`LawLibrary`] to create, [`LawInstance`] to evaluate) whatever the law is written in.

mod c_abi;
mod discover;
#[cfg(unix)]
mod elf;
pub mod inflight;
mod rust;

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Serialize;

use crate::contract::{LawInput, LawOutput, Regime};
use crate::describe::{check_params, values_to_table, LawDescription, ParamError, ParamValue};
use crate::law::{create_from_table, describe, Law};

pub use discover::{
    discover, load_paths, plugin_file_name, LawListing, LawRegistry, WritableWarning,
    PLUGIN_PATH_ENV,
};

/// Which ABI a library was loaded through.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Abi {
    /// A Rust library exporting an abi_stable module (layout-checked).
    Rust,
    /// A library exporting the C symbols of `tribo_law.h`.
    C,
    /// A law linked into the host process (tests and benchmarks).
    InProcess,
}

impl fmt::Display for Abi {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Abi::Rust => "rust",
            Abi::C => "c",
            Abi::InProcess => "in-process",
        })
    }
}

/// Everything that can go wrong finding, loading, creating or evaluating a law. Each message
/// names the file and the law where known, and says what to do.
#[derive(Debug, thiserror::Error)]
pub enum LawError {
    /// The file could not be opened as a shared library.
    #[error("`{path}` is not a loadable shared library for this machine ({reason}); a law plugin is a .so/.dylib/.dll built for this platform, e.g. by `cargo build --release`")]
    NotALibrary {
        /// File.
        path: PathBuf,
        /// What the dynamic loader said.
        reason: String,
    },
    /// A shared library without the Tribo version symbol.
    #[error("`{path}` is a shared library but not a Tribo law: it does not export `tribo_law_contract_version` (see plugin-api/include/tribo_law.h, or use tribo_plugin_api::export_law! in Rust)")]
    NoTriboSymbols {
        /// File.
        path: PathBuf,
    },
    /// Built against another contract version.
    #[error("`{path}` was built against law contract version {found}, but this tribo speaks version {expected} and still loads versions {oldest} to {expected}; rebuild the plugin against this Tribo's plugin-api")]
    ContractMismatch {
        /// File.
        path: PathBuf,
        /// Version the library reports.
        found: u32,
        /// Newest version of this host ([`crate::CONTRACT_VERSION`]).
        expected: u32,
        /// Oldest version this host still loads ([`crate::contract::OLDEST_CONTRACT_VERSION`]).
        oldest: u32,
    },
    /// A required C symbol is missing.
    #[error("`{path}` exports `tribo_law_contract_version` but not `{symbol}`; a C law must export all seven functions of tribo_law.h")]
    MissingSymbol {
        /// File.
        path: PathBuf,
        /// Missing symbol.
        symbol: String,
    },
    /// abi_stable refused the library (layout or version).
    #[error("`{path}` failed the Rust plugin ABI check: {detail}")]
    AbiCheck {
        /// File.
        path: PathBuf,
        /// abi_stable's explanation.
        detail: String,
    },
    /// The law's description is unusable.
    #[error("`{path}`: the law's description is invalid: {detail}")]
    BadDescription {
        /// File.
        path: PathBuf,
        /// What is wrong.
        detail: String,
    },
    /// Two libraries claim the same law name.
    #[error("two libraries provide the law `{name}`: `{first}` and `{second}`; remove one or point {env} elsewhere", env = PLUGIN_PATH_ENV)]
    DuplicateName {
        /// Law name.
        name: String,
        /// First file.
        first: PathBuf,
        /// Second file.
        second: PathBuf,
    },
    /// No library provides the requested law.
    #[error("no law named `{name}` was found; available: {available}. Plugins are searched in --plugin paths, {env} and the directory of the tribo executable{}", broken_text(.broken), env = PLUGIN_PATH_ENV)]
    UnknownLaw {
        /// Requested name.
        name: String,
        /// Comma-separated known names.
        available: String,
        /// Why each plugin file that could not be opened failed (one of them may be the law).
        broken: Vec<String>,
    },
    /// A parameter was rejected.
    #[error("{error} (library `{path}`)")]
    Param {
        /// The parameter problem (in the message, not a `source`: the CLI prints the chain of
        /// sources, which would repeat it).
        error: ParamError,
        /// File.
        path: PathBuf,
    },
    /// The law panicked or reported an error.
    #[error("law `{law}` (library `{path}`) failed in {stage}: {message}")]
    LawFailed {
        /// Law name.
        law: String,
        /// File.
        path: PathBuf,
        /// `create`, `evaluate` or `commit`.
        stage: &'static str,
        /// Panic message or error code.
        message: String,
    },
    /// A state slice whose length differs from the instance's declared state size was passed
    /// to `evaluate` or `commit`; the law is not called (a C law would read or write out of
    /// bounds).
    #[error("law `{law}` (library `{path}`): {stage} was given a state of {given} values, but the instance declares {expected}; the law was not called")]
    StateLength {
        /// Law name.
        law: String,
        /// File.
        path: PathBuf,
        /// `evaluate` or `commit`.
        stage: &'static str,
        /// Declared state size.
        expected: usize,
        /// Length of the slice passed.
        given: usize,
    },
    /// The law declared a state size above [`MAX_STATE_SIZE`], or the host could not allocate
    /// its state.
    #[error("law `{law}` (library `{path}`) declares a state of {size} values; {reason}")]
    StateTooLarge {
        /// Law name.
        law: String,
        /// File.
        path: PathBuf,
        /// Declared state size.
        size: usize,
        /// Above the cap, or the allocation failure.
        reason: String,
    },
    /// The law returned a regime value the contract does not define (0 to 3).
    #[error("law `{law}` (library `{path}`) returned regime {value} from evaluate, which the contract does not define (0 none, 1 boundary, 2 mixed, 3 hydrodynamic)")]
    UndefinedRegime {
        /// Law name.
        law: String,
        /// File.
        path: PathBuf,
        /// The raw value returned.
        value: u32,
    },
    /// A batch whose lengths do not fit ([`LawInstance::evaluate_many`]); the law is not
    /// called.
    #[error(
        "law `{law}` (library `{path}`): evaluate_many was given {detail}; the law was not called"
    )]
    BatchShape {
        /// Law name.
        law: String,
        /// File.
        path: PathBuf,
        /// The lengths given and what they must be.
        detail: String,
    },
    /// The file was left unopened: opening it elsewhere (a worker process) ended, crashed or
    /// hung that process.
    #[error("`{path}` was not opened: {reason}")]
    Skipped {
        /// File.
        path: PathBuf,
        /// What happened when it was opened elsewhere.
        reason: String,
    },
    /// A directory of the plugin path could not be read.
    #[error("cannot read plugin directory `{path}`: {error}")]
    Io {
        /// Directory.
        path: PathBuf,
        /// OS error (in the message, not a `source`, so it is printed once).
        error: std::io::Error,
    },
}

/// The tail of [`LawError::UnknownLaw`]'s message naming the files that could not be opened.
fn broken_text(broken: &[String]) -> String {
    match broken.len() {
        0 => String::new(),
        1 => format!(
            ". One plugin file could not be opened, perhaps the law you meant: {}",
            broken[0]
        ),
        n => format!(
            ". {n} plugin files could not be opened, perhaps one is the law you meant: {}",
            broken.join("; ")
        ),
    }
}

/// The largest state a law instance may declare, in `f64` values (2^20, 8 MiB). A larger
/// declaration is refused with [`LawError::StateTooLarge`] when the instance is created, so a
/// plugin cannot make the host abort on an impossible allocation.
pub const MAX_STATE_SIZE: usize = 1 << 20;

/// A loaded law library: its description and the means to create instances.
pub struct LawLibrary {
    description: LawDescription,
    path: PathBuf,
    abi: Abi,
    /// The contract version the library was built against (older ones are adapted).
    contract_version: u32,
    backend: LibBackend,
    /// Names this law in crash and hang reports ([`inflight`]).
    code: inflight::CodeId,
}

enum LibBackend {
    Rust(rust::RustLib),
    C(Arc<c_abi::CLib>),
    InProcess(fn(&toml::Table) -> Result<Box<dyn DynLaw>, ParamError>),
}

impl fmt::Debug for LawLibrary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("LawLibrary")
            .field("name", &self.description.name)
            .field("path", &self.path)
            .field("abi", &self.abi)
            .finish()
    }
}

impl LawLibrary {
    /// Load the library at `path`, through whichever ABI it exports. The contract version
    /// symbol is checked before any other symbol is touched.
    pub fn load(path: &Path) -> Result<Self, LawError> {
        let loading = inflight::register(loading_text(path));
        let _running = inflight::enter(loading);
        // SAFETY: loading a shared library runs its initialisers; a Tribo plugin is trusted
        // native code by design (the user chose to put it on the plugin path).
        // A bare file name would make the dynamic loader search the system's library path
        // instead of the current directory the user meant.
        let open_path = if path.parent().is_some_and(|p| p.as_os_str().is_empty()) {
            Path::new(".").join(path)
        } else {
            path.to_path_buf()
        };
        // A file cut short would be mapped and then kill this process with SIGBUS.
        #[cfg(unix)]
        elf::check(&open_path).map_err(|reason| LawError::NotALibrary {
            path: path.to_path_buf(),
            reason,
        })?;
        // Never closed, even when refused below: a library's constructors may have started
        // threads that run its code (c_abi::CLib).
        let lib = std::mem::ManuallyDrop::new(
            unsafe { libloading::Library::new(&open_path) }.map_err(|e| LawError::NotALibrary {
                path: path.to_path_buf(),
                reason: e.to_string(),
            })?,
        );
        let version = {
            // SAFETY: the contract defines this symbol as `uint32_t (void)`.
            let sym = unsafe { lib.get::<extern "C" fn() -> u32>(b"tribo_law_contract_version\0") }
                .map_err(|_| LawError::NoTriboSymbols {
                    path: path.to_path_buf(),
                })?;
            sym()
        };
        if !(crate::contract::OLDEST_CONTRACT_VERSION..=crate::CONTRACT_VERSION).contains(&version)
        {
            return Err(LawError::ContractMismatch {
                path: path.to_path_buf(),
                found: version,
                expected: crate::CONTRACT_VERSION,
                oldest: crate::contract::OLDEST_CONTRACT_VERSION,
            });
        }
        if rust::exports_rust_module(&lib) {
            let lib = rust::RustLib::load(&open_path, version)?;
            let mut description = lib.describe(path)?;
            description.suits = lib.suits();
            Ok(Self {
                code: law_code(&description.name, path),
                description,
                path: path.to_path_buf(),
                abi: Abi::Rust,
                contract_version: version,
                backend: LibBackend::Rust(lib),
            })
        } else {
            let lib = c_abi::CLib::load(path, lib, version)?;
            let description = lib.describe(path)?;
            Ok(Self {
                code: law_code(&description.name, path),
                description,
                path: path.to_path_buf(),
                abi: Abi::C,
                contract_version: version,
                backend: LibBackend::C(Arc::new(lib)),
            })
        }
    }

    /// Wrap a law linked into this process, so tests and benchmarks use the same handle.
    pub fn in_process<L: Law>() -> Result<Self, ParamError> {
        fn create<L: Law>(table: &toml::Table) -> Result<Box<dyn DynLaw>, ParamError> {
            Ok(Box::new(create_from_table::<L>(table)?))
        }
        let path = PathBuf::from(format!("<in-process {}>", L::NAME));
        Ok(Self {
            code: law_code(L::NAME, &path),
            description: describe::<L>()?,
            path,
            abi: Abi::InProcess,
            contract_version: crate::CONTRACT_VERSION,
            backend: LibBackend::InProcess(create::<L>),
        })
    }

    /// The law's self-description.
    pub fn description(&self) -> &LawDescription {
        &self.description
    }

    /// Law name.
    pub fn name(&self) -> &str {
        &self.description.name
    }

    /// File the law was loaded from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// ABI the law was loaded through.
    pub fn abi(&self) -> Abi {
        self.abi
    }

    /// The contract version the library was built against: [`crate::CONTRACT_VERSION`], or an
    /// older one the host adapts (a version-1 law sees the version-1 fields only).
    pub fn contract_version(&self) -> u32 {
        self.contract_version
    }

    /// The bearing types the law declares it suits (`SUITS_*` bits; 0 any, also for every
    /// library older than contract version 3).
    pub fn suits(&self) -> u32 {
        self.description.suits
    }

    /// Create an instance from a parameter table (missing keys take their defaults). Names,
    /// types and ranges are checked against the description for every ABI.
    pub fn create(&self, params: &toml::Table) -> Result<LawInstance, LawError> {
        let values = check_params(&self.description, params).map_err(|e| self.param_error(e))?;
        let _running = inflight::enter(self.code);
        let backend = match &self.backend {
            LibBackend::Rust(lib) => {
                // Only the keys given cross (checked and converted): the law's side fills in
                // the same defaults from the same description, and knows what was given.
                let text = toml::to_string(&values_to_table(&given_values(&values, params)))
                    .map_err(|e| {
                        self.param_error(ParamError::new("", e.to_string()).for_law(self.name()))
                    })?;
                lib.create(&text, self)?
            }
            LibBackend::C(lib) => {
                let mut flat = Vec::with_capacity(values.len());
                for (name, v) in &values {
                    match v {
                        ParamValue::Number(x) => flat.push(*x),
                        _ => {
                            return Err(self.param_error(
                                ParamError::new(name, "C laws take numeric parameters only")
                                    .for_law(self.name()),
                            ))
                        }
                    }
                }
                InstBackend::C(c_abi::CInstance::create(lib.clone(), &flat, self)?)
            }
            LibBackend::InProcess(create) => {
                let table = values_to_table(&given_values(&values, params));
                InstBackend::InProcess(create(&table).map_err(|e| self.param_error(e))?)
            }
        };
        let state_size = match &backend {
            InstBackend::Rust(obj) => obj.state_size(),
            InstBackend::RustV2(obj) => obj.state_size(),
            InstBackend::RustV1(obj) => obj.state_size(),
            InstBackend::C(inst) => inst.state_size(),
            InstBackend::InProcess(law) => law.state_size(),
        };
        if state_size > MAX_STATE_SIZE {
            return Err(LawError::StateTooLarge {
                law: self.description.name.clone(),
                path: self.path.clone(),
                size: state_size,
                reason: format!("the host allows at most {MAX_STATE_SIZE} (tribo_plugin_api::loader::MAX_STATE_SIZE)"),
            });
        }
        Ok(LawInstance {
            name: self.description.name.clone().into(),
            path: self.path.clone().into(),
            state_size,
            backend,
            code: self.code,
        })
    }

    fn param_error(&self, e: ParamError) -> LawError {
        LawError::Param {
            error: e,
            path: self.path.clone(),
        }
    }

    fn failed(&self, stage: &'static str, message: String) -> LawError {
        LawError::LawFailed {
            law: self.description.name.clone(),
            path: self.path.clone(),
            stage,
            message,
        }
    }
}

/// The checked `values` of the keys `params` gives, in the description's order.
fn given_values(
    values: &[(String, ParamValue)],
    params: &toml::Table,
) -> Vec<(String, ParamValue)> {
    values
        .iter()
        .filter(|(name, _)| params.contains_key(name))
        .cloned()
        .collect()
}

/// The crash-report name of law `name` from `path`.
/// How the code running while `path` is loaded is named in failure messages.
fn loading_text(path: &Path) -> String {
    format!("library `{}` (while loading it)", path.display())
}

/// The library a failure message says was being loaded when it happened, if any: the path
/// in the first "library `PATH` (while loading it)" of `message`.
pub fn loading_library(message: &str) -> Option<PathBuf> {
    const HEAD: &str = "library `";
    const TAIL: &str = "` (while loading it)";
    let end = message.find(TAIL)?;
    let start = message[..end].rfind(HEAD)? + HEAD.len();
    Some(PathBuf::from(&message[start..end]))
}

fn law_code(name: &str, path: &Path) -> inflight::CodeId {
    inflight::register(format!("law `{name}` ({})", path.display()))
}

/// Object-safe view of an in-process [`Law`].
trait DynLaw: Send + Sync {
    fn state_size(&self) -> usize;
    fn evaluate(&self, input: &LawInput, state: &[f64]) -> LawOutput;
    fn evaluate_many(
        &self,
        inputs: &[LawInput],
        states: &[f64],
        stride: usize,
        outputs: &mut [LawOutput],
    );
    fn commit(&self, input: &LawInput, state: &mut [f64]);
}

impl<L: Law> DynLaw for L {
    fn state_size(&self) -> usize {
        Law::state_size(self)
    }
    fn evaluate(&self, input: &LawInput, state: &[f64]) -> LawOutput {
        Law::evaluate(self, input, state)
    }
    fn evaluate_many(
        &self,
        inputs: &[LawInput],
        states: &[f64],
        stride: usize,
        outputs: &mut [LawOutput],
    ) {
        Law::evaluate_many(self, inputs, states, stride, outputs)
    }
    fn commit(&self, input: &LawInput, state: &mut [f64]) {
        Law::commit(self, input, state)
    }
}

enum InstBackend {
    Rust(crate::rust_abi::RLawBox),
    /// A library built against contract version 2: handed the version-2 view of the input,
    /// its output completed by the host.
    RustV2(crate::rust_abi::v2::RLawBox),
    /// A library built against contract version 1: handed the version-1 view of the input,
    /// its output completed by the host.
    RustV1(crate::rust_abi::v1::RLawBox),
    C(c_abi::CInstance),
    InProcess(Box<dyn DynLaw>),
}

/// A failed [`LawInstance::evaluate_many`]: the error, and the input of the batch it belongs
/// to (`None` when the batch itself was malformed, or failed though every input evaluates
/// alone).
#[derive(Debug, thiserror::Error)]
#[error("{}{error}", .index.map(|k| format!("batch input {k}: ")).unwrap_or_default())]
pub struct BatchError {
    /// Index of the input the law failed at.
    pub index: Option<usize>,
    /// What went wrong (in the message, not a `source`, so it is printed once).
    pub error: LawError,
}

/// A created law instance: what the solver calls once per joint and step. The host keeps the
/// instance's state array (of [`LawInstance::state_size`] values, zero-initialised).
pub struct LawInstance {
    name: Arc<str>,
    path: Arc<Path>,
    state_size: usize,
    backend: InstBackend,
    /// Names this law in crash and hang reports ([`inflight`]).
    code: inflight::CodeId,
}

impl fmt::Debug for LawInstance {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("LawInstance")
            .field("name", &self.name)
            .field("path", &self.path)
            .field("state_size", &self.state_size)
            .finish()
    }
}

impl LawInstance {
    /// Law name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Library file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Number of state variables the host must keep.
    pub fn state_size(&self) -> usize {
        self.state_size
    }

    /// Name the joint this instance is bound to in crash and hang reports ("law `x` (file) at
    /// joint `piston`"), so a watchdog or a parent process can say where a stuck or crashing
    /// call was made.
    pub fn set_joint(&mut self, joint: &str) {
        self.code = inflight::register(format!(
            "law `{}` ({}) at joint `{joint}`",
            self.name,
            self.path.display()
        ));
    }

    /// Whether the law evaluates a batch itself ([`LawInstance::evaluate_many`] makes one call
    /// into the library): a version-3 Rust law, a C law exporting `tribo_law_evaluate_many`,
    /// an in-process law. Otherwise the host loops over the batch.
    pub fn evaluates_batches(&self) -> bool {
        match &self.backend {
            InstBackend::Rust(_) | InstBackend::InProcess(_) => true,
            InstBackend::C(inst) => inst.has_evaluate_many(),
            InstBackend::RustV2(_) | InstBackend::RustV1(_) => false,
        }
    }

    /// A zero-initialised state of [`LawInstance::state_size`] values. The allocation is
    /// fallible: failure is [`LawError::StateTooLarge`], not an abort.
    pub fn new_state(&self) -> Result<Vec<f64>, LawError> {
        let mut state = Vec::new();
        state
            .try_reserve_exact(self.state_size)
            .map_err(|e| LawError::StateTooLarge {
                law: self.name.to_string(),
                path: self.path.to_path_buf(),
                size: self.state_size,
                reason: format!("the host could not allocate it ({e})"),
            })?;
        state.resize(self.state_size, 0.0);
        Ok(state)
    }

    /// Evaluate the law. A panic inside a Rust law, or a non-zero status from a C law, comes
    /// back as [`LawError::LawFailed`] naming the law; the host process survives. A `state`
    /// whose length is not [`LawInstance::state_size`] is [`LawError::StateLength`] (the law is
    /// not called), and a regime outside the contract's values is
    /// [`LawError::UndefinedRegime`], so every output returned has a defined
    /// [`LawOutput::regime`]. A law built against an older contract gets its version's view of
    /// the input, and its output has the later fields zero and only the flags it knew.
    #[inline]
    pub fn evaluate(&self, input: &LawInput, state: &[f64]) -> Result<LawOutput, LawError> {
        let mut out = LawOutput::force(0.0);
        self.evaluate_into(input, state, &mut out)?;
        Ok(out)
    }

    /// [`LawInstance::evaluate`] into an output the caller owns: the solver's form, with no
    /// output moved through a `Result`. On an error `out` holds whatever the law left in it.
    #[inline]
    pub fn evaluate_into(
        &self,
        input: &LawInput,
        state: &[f64],
        out: &mut LawOutput,
    ) -> Result<(), LawError> {
        self.check_state("evaluate", state.len())?;
        let mut round = inflight::round();
        // SAFETY: the state's length was checked just above.
        unsafe { self.evaluate_in_round(input, state, out, &mut round) }
    }

    /// [`LawInstance::evaluate_into`] for the solver's hot loop: the call marked through a
    /// [`inflight::Round`] the caller holds for a whole round of law calls, and the state's
    /// length not checked here (the caller checked it once, when it bound the law and made
    /// the state). Every other check of `evaluate_into` is made.
    ///
    /// # Safety
    /// `state.len()` must be [`LawInstance::state_size`]: a C law reads and writes that many
    /// values through the pointer.
    #[inline]
    pub unsafe fn evaluate_in_round(
        &self,
        input: &LawInput,
        state: &[f64],
        out: &mut LawOutput,
        round: &mut inflight::Round,
    ) -> Result<(), LawError> {
        debug_assert_eq!(state.len(), self.state_size);
        let _running = round.enter_call(self.code, input);
        self.call_into(input, state, out)?;
        if Regime::from_u32(out.regime).is_none() {
            return Err(self.undefined_regime(out.regime));
        }
        Ok(())
    }

    /// One call of the law into `out`, the state's length already checked and the law marked
    /// as running.
    #[inline]
    fn call_into(
        &self,
        input: &LawInput,
        state: &[f64],
        out: &mut LawOutput,
    ) -> Result<(), LawError> {
        use abi_stable::std_types::RResult::{RErr, ROk};
        let old = |r: abi_stable::std_types::RResult<crate::contract::v2::LawOutput, _>,
                   out: &mut LawOutput| match r {
            ROk(v2) => {
                *out = LawOutput::from(&v2);
                Ok(())
            }
            RErr(msg) => Err(self.failed("evaluate", format!("panicked: {msg}"))),
        };
        match &self.backend {
            InstBackend::Rust(obj) => match obj.evaluate_into(input, state.into(), out) {
                ROk(()) => Ok(()),
                RErr(msg) => Err(self.failed("evaluate", format!("panicked: {msg}"))),
            },
            InstBackend::RustV2(obj) => old(obj.evaluate(input.as_v2(), state.into()), out),
            InstBackend::RustV1(obj) => old(obj.evaluate(input.as_v1(), state.into()), out),
            InstBackend::C(inst) => inst
                .evaluate_into(input, state, out)
                .map_err(|code| self.failed("evaluate", format!("returned error code {code}"))),
            InstBackend::InProcess(law) => {
                *out = law.evaluate(input, state);
                Ok(())
            }
        }
    }

    /// Evaluate `inputs` into `outputs` (as many), input `k` with the state starting at
    /// `states[k * state_stride]` (`state_stride` 0: every input shares the one state
    /// `states`, of [`LawInstance::state_size`] values). One call into the library when it
    /// evaluates batches itself ([`LawInstance::evaluates_batches`]), else a loop here; either
    /// way each output is what [`LawInstance::evaluate`] gives for its input.
    ///
    /// # Errors
    /// Lengths that do not fit (checked before the law is called), or the first input the
    /// law fails at, with its index: a failed batch is evaluated again one input at a time to
    /// find it, so the error is the one that input gives alone.
    pub fn evaluate_many(
        &self,
        inputs: &[LawInput],
        states: &[f64],
        state_stride: usize,
        outputs: &mut [LawOutput],
    ) -> Result<(), BatchError> {
        self.check_batch(inputs.len(), states.len(), state_stride, outputs.len())?;
        // A stateless law reads no state: one shared empty slice, whatever the caller passed.
        let (states, stride) = if self.state_size == 0 {
            (&states[..0], 0)
        } else {
            (states, state_stride)
        };
        let _running = inflight::enter(self.code);
        let native = match &self.backend {
            InstBackend::Rust(obj) => Some(
                match obj.evaluate_many(inputs.into(), states.into(), stride, outputs.into()) {
                    abi_stable::std_types::RResult::ROk(()) => Ok(()),
                    abi_stable::std_types::RResult::RErr(msg) => Err(format!("panicked: {msg}")),
                },
            ),
            InstBackend::C(inst) if inst.has_evaluate_many() => Some(
                inst.evaluate_many(inputs, states, stride, outputs)
                    .map_err(|code| format!("tribo_law_evaluate_many returned error code {code}")),
            ),
            InstBackend::InProcess(law) => {
                law.evaluate_many(inputs, states, stride, outputs);
                Some(Ok(()))
            }
            _ => None,
        };
        match native {
            Some(Ok(())) => match outputs
                .iter()
                .position(|o| Regime::from_u32(o.regime).is_none())
            {
                None => Ok(()),
                Some(k) => Err(BatchError {
                    index: Some(k),
                    error: self.undefined_regime(outputs[k].regime),
                }),
            },
            Some(Err(message)) => {
                Err(self.locate_batch_failure(inputs, states, stride, outputs, message))
            }
            None => {
                for (k, (input, out)) in inputs.iter().zip(outputs.iter_mut()).enumerate() {
                    let state = &states[k * stride..k * stride + self.state_size];
                    // Each call marked with its input, so a stuck one is reported with it.
                    let _call = inflight::enter_call(self.code, input);
                    self.call_into(input, state, out)
                        .and_then(|()| match Regime::from_u32(out.regime) {
                            Some(_) => Ok(()),
                            None => Err(self.undefined_regime(out.regime)),
                        })
                        .map_err(|error| BatchError {
                            index: Some(k),
                            error,
                        })?;
                }
                Ok(())
            }
        }
    }

    /// A batch call failed with `message`: evaluate its inputs one at a time and blame the
    /// first that fails alone; if none does, the batch call itself is the failure.
    #[cold]
    fn locate_batch_failure(
        &self,
        inputs: &[LawInput],
        states: &[f64],
        stride: usize,
        outputs: &mut [LawOutput],
        message: String,
    ) -> BatchError {
        for (k, (input, out)) in inputs.iter().zip(outputs.iter_mut()).enumerate() {
            let state = &states[k * stride..k * stride + self.state_size];
            if let Err(error) = self.evaluate_into(input, state, out) {
                return BatchError {
                    index: Some(k),
                    error,
                };
            }
        }
        BatchError {
            index: None,
            error: self.failed(
                "evaluate_many",
                format!(
                    "{message}, though each of its {} inputs evaluates alone",
                    inputs.len()
                ),
            ),
        }
    }

    /// The lengths of a batch: as many outputs as inputs, and a state for every input.
    #[inline]
    fn check_batch(
        &self,
        n: usize,
        states: usize,
        stride: usize,
        outputs: usize,
    ) -> Result<(), BatchError> {
        let size = self.state_size;
        let needed = match (n, stride) {
            _ if size == 0 => Some(0),
            (0, _) => Some(0),
            (_, 0) => Some(size),
            (n, s) if s >= size => (n - 1).checked_mul(s).and_then(|x| x.checked_add(size)),
            _ => None,
        };
        let fits = outputs == n
            && match needed {
                Some(needed) if stride == 0 => states == needed || size == 0,
                Some(needed) => states >= needed,
                None => false,
            };
        if fits {
            Ok(())
        } else {
            Err(self.bad_batch(n, states, stride, outputs))
        }
    }

    #[cold]
    fn bad_batch(&self, n: usize, states: usize, stride: usize, outputs: usize) -> BatchError {
        BatchError {
            index: None,
            error: LawError::BatchShape {
                law: self.name.to_string(),
                path: self.path.to_path_buf(),
                detail: format!(
                    "{n} inputs, {outputs} outputs, {states} state values at a stride of {stride}, for a state of {} values per input (stride 0: one shared state of exactly that length; otherwise a stride of at least that and room for every input's state)",
                    self.state_size
                ),
            },
        }
    }

    /// Advance the host-owned `state` over an accepted step. A `state` whose length is not
    /// [`LawInstance::state_size`] is [`LawError::StateLength`] and the law is not called.
    pub fn commit(&self, input: &LawInput, state: &mut [f64]) -> Result<(), LawError> {
        self.check_state("commit", state.len())?;
        let _running = inflight::enter_call(self.code, input);
        match &self.backend {
            InstBackend::Rust(obj) => match obj.commit(input, state.into()) {
                abi_stable::std_types::RResult::ROk(()) => Ok(()),
                abi_stable::std_types::RResult::RErr(msg) => {
                    Err(self.failed("commit", format!("panicked: {msg}")))
                }
            },
            InstBackend::RustV2(obj) => match obj.commit(input.as_v2(), state.into()) {
                abi_stable::std_types::RResult::ROk(()) => Ok(()),
                abi_stable::std_types::RResult::RErr(msg) => {
                    Err(self.failed("commit", format!("panicked: {msg}")))
                }
            },
            InstBackend::RustV1(obj) => match obj.commit(input.as_v1(), state.into()) {
                abi_stable::std_types::RResult::ROk(()) => Ok(()),
                abi_stable::std_types::RResult::RErr(msg) => {
                    Err(self.failed("commit", format!("panicked: {msg}")))
                }
            },
            InstBackend::C(inst) => inst
                .commit(input, state)
                .map_err(|code| self.failed("commit", format!("returned error code {code}"))),
            InstBackend::InProcess(law) => {
                law.commit(input, state);
                Ok(())
            }
        }
    }

    #[inline]
    fn check_state(&self, stage: &'static str, given: usize) -> Result<(), LawError> {
        if given == self.state_size {
            Ok(())
        } else {
            Err(self.wrong_state(stage, given))
        }
    }

    #[cold]
    fn wrong_state(&self, stage: &'static str, given: usize) -> LawError {
        LawError::StateLength {
            law: self.name.to_string(),
            path: self.path.to_path_buf(),
            stage,
            expected: self.state_size,
            given,
        }
    }

    #[cold]
    fn undefined_regime(&self, value: u32) -> LawError {
        LawError::UndefinedRegime {
            law: self.name.to_string(),
            path: self.path.to_path_buf(),
            value,
        }
    }

    #[cold]
    fn failed(&self, stage: &'static str, message: String) -> LawError {
        LawError::LawFailed {
            law: self.name.to_string(),
            path: self.path.to_path_buf(),
            stage,
            message,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contract::JointKind;
    use crate::describe::ParamSpec;

    /// Parameters of [`Stateful`].
    #[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
    #[serde(deny_unknown_fields, default)]
    struct Params {
        n: f64,
        regime: f64,
    }

    impl Default for Params {
        fn default() -> Self {
            Self {
                n: 3.0,
                regime: 0.0,
            }
        }
    }

    /// A law with `n` state values that writes every one of them in commit, and reports the
    /// raw regime it was given.
    struct Stateful(Params);

    impl Law for Stateful {
        type Params = Params;
        const NAME: &'static str = "test-stateful";
        const VERSION: &'static str = "0.0.0";
        const SUMMARY: &'static str = "test law";
        fn parameters() -> Vec<ParamSpec> {
            vec![
                ParamSpec::number("n", "-", "state size", 0.0, 1e12),
                ParamSpec::number("regime", "-", "raw regime", 0.0, 100.0),
            ]
        }
        fn new(p: Params) -> Result<Self, ParamError> {
            Ok(Self(p))
        }
        fn state_size(&self) -> usize {
            self.0.n as usize
        }
        fn evaluate(&self, _: &LawInput, state: &[f64]) -> LawOutput {
            let mut out = LawOutput::force(-state.iter().sum::<f64>());
            out.regime = self.0.regime as u32;
            out
        }
        fn commit(&self, _: &LawInput, state: &mut [f64]) {
            // Indexes up to its declared size: a short slice would panic here.
            let n = Law::state_size(self);
            state[..n].iter_mut().for_each(|x| *x += 1.0);
        }
    }

    fn create(params: &str) -> LawInstance {
        let lib = LawLibrary::in_process::<Stateful>().expect("describes itself");
        lib.create(&params.parse().expect("TOML")).expect("creates")
    }

    #[test]
    fn a_wrong_length_state_is_an_error_naming_law_and_lengths() {
        let law = create("n = 3");
        let input = LawInput::at_rest(JointKind::Revolute);
        let mut state = law.new_state().expect("allocates");
        assert_eq!(state, vec![0.0; 3]);
        law.commit(&input, &mut state)
            .expect("right length commits");
        assert_eq!(law.evaluate(&input, &state).expect("evaluates").force, -3.0);
        for len in [0, 2, 4] {
            let mut short = vec![0.0; len];
            for e in [
                law.evaluate(&input, &short).unwrap_err(),
                law.commit(&input, &mut short).unwrap_err(),
            ] {
                let msg = e.to_string();
                assert!(
                    matches!(e, LawError::StateLength { expected: 3, given, .. } if given == len),
                    "{msg}"
                );
                assert!(
                    msg.contains("test-stateful")
                        && msg.contains(&format!("{len} values"))
                        && msg.contains("declares 3"),
                    "{msg}"
                );
            }
            // The law was not called: nothing was written.
            assert!(short.iter().all(|&x| x == 0.0));
        }
    }

    #[test]
    fn evaluate_many_equals_evaluate_with_shared_and_strided_states() {
        let law = create("n = 3");
        let inputs: Vec<LawInput> = (0..5)
            .map(|k| LawInput::at_rest(JointKind::Revolute).with_velocity(k as f64))
            .collect();
        let mut outputs = vec![LawOutput::force(9.0); 5];
        // One shared state.
        law.evaluate_many(&inputs, &[1.0, 2.0, 3.0], 0, &mut outputs)
            .expect("fits");
        assert!(outputs.iter().all(|o| o.force == -6.0));
        // A state per input at a stride of 4; the gaps are never read.
        let mut states = vec![f64::NAN; 4 * 4 + 3];
        for k in 0..5 {
            states[4 * k..4 * k + 3].copy_from_slice(&[k as f64, 1.0, 0.5]);
        }
        law.evaluate_many(&inputs, &states, 4, &mut outputs)
            .expect("fits");
        for (k, o) in outputs.iter().enumerate() {
            let alone = law.evaluate(&inputs[k], &states[4 * k..4 * k + 3]);
            assert_eq!(alone.expect("evaluates").force, o.force);
            assert_eq!(o.force, -(k as f64 + 1.5));
        }
        // An empty batch is nothing to do.
        law.evaluate_many(&[], &[], 3, &mut []).expect("empty");
    }

    #[test]
    fn batches_that_do_not_fit_are_refused_before_the_law_is_called() {
        let law = create("n = 3");
        let inputs = vec![LawInput::at_rest(JointKind::Revolute); 2];
        let mut two = vec![LawOutput::force(7.0); 2];
        for (states, stride, outputs) in [
            (4, 0, 2), // a shared state of the wrong length
            (5, 3, 2), // no room for the second state
            (6, 2, 2), // a stride shorter than the state
            (6, 3, 1), // fewer outputs than inputs
        ] {
            let e = law
                .evaluate_many(&inputs, &vec![0.0; states], stride, &mut two[..outputs])
                .unwrap_err();
            assert_eq!(e.index, None);
            let msg = e.to_string();
            assert!(
                matches!(e.error, LawError::BatchShape { .. })
                    && msg.contains("test-stateful")
                    && msg.contains(&format!("stride of {stride}")),
                "{msg}"
            );
        }
        assert!(two.iter().all(|o| o.force == 7.0), "the law was called");
        // A stateless law reads no state, whatever the stride.
        let stateless = create("n = 0");
        stateless
            .evaluate_many(&inputs, &[], 5, &mut two)
            .expect("no state to fit");
        assert!(two.iter().all(|o| o.force == 0.0));
    }

    #[test]
    fn a_batch_names_the_input_with_an_undefined_regime() {
        let law = create("n = 0\nregime = 7");
        let inputs = vec![LawInput::at_rest(JointKind::Prismatic); 3];
        let mut out = vec![LawOutput::force(0.0); 3];
        let e = law.evaluate_many(&inputs, &[], 0, &mut out).unwrap_err();
        assert_eq!(e.index, Some(0));
        assert!(
            matches!(e.error, LawError::UndefinedRegime { value: 7, .. }),
            "{e}"
        );
        assert!(e.to_string().starts_with("batch input 0: "), "{e}");
    }

    #[test]
    fn undefined_regimes_are_refused_and_defined_ones_pass() {
        let input = LawInput::at_rest(JointKind::Prismatic);
        for raw in 0..=3 {
            let law = create(&format!("n = 0\nregime = {raw}"));
            let out = law.evaluate(&input, &[]).expect("defined regime");
            assert_eq!(out.regime().map(|r| r as u32), Some(raw));
        }
        for raw in [4, 42] {
            let law = create(&format!("n = 0\nregime = {raw}"));
            let e = law.evaluate(&input, &[]).unwrap_err();
            let msg = e.to_string();
            assert!(
                matches!(e, LawError::UndefinedRegime { value, .. } if value == raw),
                "{msg}"
            );
            assert!(
                msg.contains("test-stateful") && msg.contains(&format!("regime {raw}")),
                "{msg}"
            );
        }
    }

    #[test]
    fn state_sizes_above_the_cap_are_refused_at_create() {
        let lib = LawLibrary::in_process::<Stateful>().expect("describes itself");
        let at_cap = lib
            .create(&format!("n = {MAX_STATE_SIZE}").parse().expect("TOML"))
            .expect("the cap itself is allowed");
        assert_eq!(at_cap.new_state().expect("allocates").len(), MAX_STATE_SIZE);
        let huge = MAX_STATE_SIZE + 1;
        let e = lib
            .create(&format!("n = {huge}").parse().expect("TOML"))
            .unwrap_err();
        let msg = e.to_string();
        assert!(
            matches!(e, LawError::StateTooLarge { size, .. } if size == huge),
            "{msg}"
        );
        assert!(
            msg.contains("test-stateful") && msg.contains(&huge.to_string()),
            "{msg}"
        );
    }
}
