//! Loading C ABI law libraries (`include/tribo_law.h`) with libloading.

use std::ffi::{c_char, c_void, CStr};
use std::path::Path;
use std::sync::Arc;

use super::{LawError, LawLibrary};
use crate::contract::{CLawDescription as CDescription, LawInput, LawOutput};
use crate::describe::{LawDescription, ParamError, ParamSpec, ParamValue};

type DescribeFn = unsafe extern "C" fn() -> *const CDescription;
type CreateFn = unsafe extern "C" fn(*const f64, usize, *mut c_char, usize) -> *mut c_void;
type StateSizeFn = unsafe extern "C" fn(*const c_void) -> usize;
type EvaluateFn =
    unsafe extern "C" fn(*const c_void, *const LawInput, *const f64, *mut LawOutput) -> i32;
type CommitFn = unsafe extern "C" fn(*const c_void, *const LawInput, *mut f64) -> i32;
type DestroyFn = unsafe extern "C" fn(*mut c_void);
type EvaluateManyFn = unsafe extern "C" fn(
    *const c_void,
    usize,
    *const LawInput,
    *const f64,
    usize,
    *mut LawOutput,
) -> i32;
type SuitsFn = unsafe extern "C" fn() -> u32;

/// A C law library with all its symbols resolved. The `Library` is never closed: a law's
/// threads, `atexit` handlers or thread-local destructors may still point into its code after
/// the last instance is gone, and unloading it under them would crash the process at exit.
pub(super) struct CLib {
    describe: DescribeFn,
    create: CreateFn,
    state_size: StateSizeFn,
    evaluate: EvaluateFn,
    commit: CommitFn,
    destroy: DestroyFn,
    /// `tribo_law_evaluate_many`, optional from contract version 3 (absent: the host loops).
    evaluate_many: Option<EvaluateManyFn>,
    /// `tribo_law_suits`, optional from contract version 3 (absent: 0, any joint).
    suits: Option<SuitsFn>,
    /// The contract version the library was built against.
    version: u32,
    _lib: std::mem::ManuallyDrop<libloading::Library>,
}

fn symbol<T: Copy>(lib: &libloading::Library, path: &Path, name: &str) -> Result<T, LawError> {
    let with_nul = format!("{name}\0");
    // SAFETY: the symbol's type is the one tribo_law.h declares for `name`.
    unsafe { lib.get::<T>(with_nul.as_bytes()) }
        .map(|s| *s)
        .map_err(|_| LawError::MissingSymbol {
            path: path.to_path_buf(),
            symbol: name.to_string(),
        })
}

/// Read a C string the law owns; NULL or invalid UTF-8 is a description error.
///
/// # Safety
/// `p` is NULL or points to a NUL-terminated string that outlives the call.
unsafe fn c_text(p: *const c_char, what: &str) -> Result<String, String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    // SAFETY: non-null and NUL-terminated by the caller's contract.
    unsafe { CStr::from_ptr(p) }
        .to_str()
        .map(str::to_string)
        .map_err(|_| format!("{what} is not UTF-8"))
}

impl CLib {
    /// Resolve the symbols of a library built against contract `version`. The optional
    /// symbols of version 3 are looked up only in a version-3 library: an older one cannot
    /// mean them, whatever it exports under those names.
    pub(super) fn load(
        path: &Path,
        lib: std::mem::ManuallyDrop<libloading::Library>,
        version: u32,
    ) -> Result<Self, LawError> {
        fn optional<T: Copy>(
            lib: &libloading::Library,
            path: &Path,
            version: u32,
            name: &str,
        ) -> Option<T> {
            if version >= 3 {
                symbol(lib, path, name).ok()
            } else {
                None
            }
        }
        Ok(Self {
            describe: symbol(&lib, path, "tribo_law_describe")?,
            create: symbol(&lib, path, "tribo_law_create")?,
            state_size: symbol(&lib, path, "tribo_law_state_size")?,
            evaluate: symbol(&lib, path, "tribo_law_evaluate")?,
            commit: symbol(&lib, path, "tribo_law_commit")?,
            destroy: symbol(&lib, path, "tribo_law_destroy")?,
            evaluate_many: optional(&lib, path, version, "tribo_law_evaluate_many"),
            suits: optional(&lib, path, version, "tribo_law_suits"),
            version,
            _lib: lib,
        })
    }

    /// The `SUITS_*` bits from `tribo_law_suits`, 0 (any) without it.
    pub(super) fn suits(&self) -> u32 {
        // SAFETY: the contract declares the symbol as `uint32_t (void)`.
        self.suits.map_or(0, |f| unsafe { f() })
    }

    /// Whether the library evaluates batches itself (`tribo_law_evaluate_many`).
    pub(super) fn has_evaluate_many(&self) -> bool {
        self.evaluate_many.is_some()
    }

    pub(super) fn describe(&self, path: &Path) -> Result<LawDescription, LawError> {
        let bad = |detail: String| LawError::BadDescription {
            path: path.to_path_buf(),
            detail,
        };
        // SAFETY: tribo_law_describe returns NULL or a pointer to static storage.
        let d = unsafe { (self.describe)().as_ref() }
            .ok_or_else(|| bad("tribo_law_describe returned NULL".into()))?;
        if d.n_params > 0 && d.params.is_null() {
            return Err(bad(format!(
                "n_params is {} but params is NULL",
                d.n_params
            )));
        }
        if d.n_params > 4096 {
            return Err(bad(format!(
                "n_params is {}, which is not plausible",
                d.n_params
            )));
        }
        // SAFETY: strings are static, NUL-terminated; params points to n_params entries.
        unsafe {
            let name = c_text(d.name, "name").map_err(bad)?;
            if name.is_empty() {
                return Err(bad("name is empty".into()));
            }
            let mut parameters = Vec::with_capacity(d.n_params as usize);
            for i in 0..d.n_params as usize {
                let p = &*d.params.add(i);
                let pname = c_text(p.name, &format!("params[{i}].name")).map_err(bad)?;
                let check = |ok: bool, what: &str| {
                    if ok {
                        Ok(())
                    } else {
                        Err(bad(format!("parameter `{pname}`: {what}")))
                    }
                };
                check(p.min <= p.max, "min is greater than max")?;
                check(
                    p.default_value >= p.min && p.default_value <= p.max,
                    "default is outside [min, max]",
                )?;
                parameters.push(ParamSpec {
                    unit: c_text(p.unit, &format!("`{pname}` unit")).map_err(bad)?,
                    doc: c_text(p.doc, &format!("`{pname}` doc")).map_err(bad)?,
                    name: pname,
                    default: ParamValue::Number(p.default_value),
                    min: p.min,
                    max: p.max,
                    choices: Vec::new(),
                });
            }
            Ok(LawDescription {
                name,
                version: c_text(d.version, "version").map_err(bad)?,
                summary: c_text(d.summary, "summary").map_err(bad)?,
                parameters,
                suits: self.suits(),
            })
        }
    }
}

/// A C law instance; destroyed through the library when dropped.
pub(super) struct CInstance {
    lib: Arc<CLib>,
    handle: *mut c_void,
    state_size: usize,
}

// SAFETY: the contract requires evaluate/commit to be re-entrant for a const instance and
// to keep no per-step mutable data in the instance, so it may move between and be shared by
// threads.
unsafe impl Send for CInstance {}
// SAFETY: see above.
unsafe impl Sync for CInstance {}

impl CInstance {
    pub(super) fn create(
        lib: Arc<CLib>,
        params: &[f64],
        owner: &LawLibrary,
    ) -> Result<Self, LawError> {
        let mut msg = [0 as c_char; 512];
        // SAFETY: params holds params.len() doubles; msg is a writable buffer of msg.len() bytes.
        let handle =
            unsafe { (lib.create)(params.as_ptr(), params.len(), msg.as_mut_ptr(), msg.len()) };
        if handle.is_null() {
            msg[msg.len() - 1] = 0;
            // SAFETY: the buffer was zeroed and its last byte forced to NUL.
            let text = unsafe { CStr::from_ptr(msg.as_ptr()) }
                .to_string_lossy()
                .into_owned();
            let (parameter, message) = match text.split_once(": ") {
                Some((p, m)) if owner.description.parameters.iter().any(|s| s.name == p) => {
                    (p.to_string(), m.to_string())
                }
                _ => (
                    String::new(),
                    if text.is_empty() {
                        "tribo_law_create returned NULL".into()
                    } else {
                        text
                    },
                ),
            };
            return Err(
                owner.param_error(ParamError::new(&parameter, message).for_law(owner.name()))
            );
        }
        // SAFETY: handle is a live instance from tribo_law_create.
        let state_size = unsafe { (lib.state_size)(handle) };
        Ok(Self {
            lib,
            handle,
            state_size,
        })
    }

    pub(super) fn state_size(&self) -> usize {
        self.state_size
    }

    /// Whether the library exports `tribo_law_evaluate_many`.
    pub(super) fn has_evaluate_many(&self) -> bool {
        self.lib.has_evaluate_many()
    }

    /// Evaluate into `out`, which the law finds zeroed (force 0, flags 0); what a law older
    /// than version 3 leaves is cut to its version's fields and flags.
    #[inline]
    pub(super) fn evaluate_into(
        &self,
        input: &LawInput,
        state: &[f64],
        out: &mut LawOutput,
    ) -> Result<(), i32> {
        *out = LawOutput::force(0.0);
        // SAFETY: live handle; input and out are valid for the call; state has state_size values.
        let code = unsafe { (self.lib.evaluate)(self.handle, input, state.as_ptr(), out) };
        out.limit_to_version(self.lib.version);
        if code == 0 {
            Ok(())
        } else {
            Err(code)
        }
    }

    /// One call of `tribo_law_evaluate_many` (the library has it: [`CLib::has_evaluate_many`])
    /// over `inputs`, the outputs zeroed first. The caller has checked the lengths: `outputs`
    /// as long as `inputs`, and `states` holding every input's state at `state_stride`.
    pub(super) fn evaluate_many(
        &self,
        inputs: &[LawInput],
        states: &[f64],
        state_stride: usize,
        outputs: &mut [LawOutput],
    ) -> Result<(), i32> {
        let Some(many) = self.lib.evaluate_many else {
            return Err(-1);
        };
        outputs.fill(LawOutput::force(0.0));
        // SAFETY: live handle; `inputs` and `outputs` hold inputs.len() structs, `states` every
        // input's state_size values at the stride (checked by the caller).
        let code = unsafe {
            many(
                self.handle,
                inputs.len(),
                inputs.as_ptr(),
                states.as_ptr(),
                state_stride,
                outputs.as_mut_ptr(),
            )
        };
        if code == 0 {
            Ok(())
        } else {
            Err(code)
        }
    }

    pub(super) fn commit(&self, input: &LawInput, state: &mut [f64]) -> Result<(), i32> {
        // SAFETY: as for evaluate; state is writable.
        let code = unsafe { (self.lib.commit)(self.handle, input, state.as_mut_ptr()) };
        if code == 0 {
            Ok(())
        } else {
            Err(code)
        }
    }
}

impl Drop for CInstance {
    fn drop(&mut self) {
        // SAFETY: handle came from tribo_law_create and is destroyed exactly once.
        unsafe { (self.lib.destroy)(self.handle) }
    }
}
