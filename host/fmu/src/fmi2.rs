//! The FMI 2.0 Co-Simulation C API the importer calls (`fmi2Functions.h`), each function a thin
//! shell over [`Instance`]: pointers checked, panics caught, failures logged through the
//! importer's logger and answered with `fmi2Error`, never a crash of the importer.

#![allow(non_snake_case)]

use std::ffi::{c_char, c_int, c_uint, c_void, CStr};
use std::panic::{catch_unwind, AssertUnwindSafe};

use crate::instance::{deserialize, serialize, CallResult, Instance, Saved, Value};
use crate::log::{CallbackFunctions, Logger, Status};

type Component = *mut c_void;
type Fmi2Status = c_int;
type ValueReference = c_uint;
type FmuState = *mut c_void;

const OK: Fmi2Status = Status::Ok as c_int;
const DISCARD: Fmi2Status = Status::Discard as c_int;
const ERROR: Fmi2Status = Status::Error as c_int;
const FATAL: Fmi2Status = Status::Fatal as c_int;

/// fmi2CoSimulation.
const CO_SIMULATION: c_int = 1;

/// The text of a C string, if it is one.
///
/// # Safety
/// `s` must be NULL or a valid NUL-terminated string.
unsafe fn text<'a>(s: *const c_char) -> Option<&'a str> {
    if s.is_null() {
        return None;
    }
    // SAFETY: non-NULL and NUL-terminated by the caller's guarantee.
    unsafe { CStr::from_ptr(s) }.to_str().ok()
}

/// A slice from a C array, empty for a count of 0 (where the pointer may be NULL).
///
/// # Safety
/// `p` must point to `n` valid elements when `n > 0`.
unsafe fn slice<'a, T>(p: *const T, n: usize) -> Option<&'a [T]> {
    if n == 0 {
        return Some(&[]);
    }
    if p.is_null() {
        return None;
    }
    // SAFETY: the caller guarantees `n` elements at `p`.
    Some(unsafe { std::slice::from_raw_parts(p, n) })
}

/// Run `f` on the instance behind `c`: a NULL instance is an error; a failure is logged and
/// answered with fmi2Error; a panic (a bug) with fmi2Fatal.
fn with(c: Component, call: &str, f: impl FnOnce(&mut Instance) -> CallResult<()>) -> Fmi2Status {
    if c.is_null() {
        return ERROR;
    }
    // SAFETY: `c` came from fmi2Instantiate (Box<Instance>) and the importer calls one
    // instance from one thread at a time (FMI 2.0, 2.1.4).
    let inst = unsafe { &mut *c.cast::<Instance>() };
    match catch_unwind(AssertUnwindSafe(|| f(inst))) {
        Ok(Ok(())) => OK,
        Ok(Err(message)) => {
            inst.log.error(&format!("{call}: {message}"));
            ERROR
        }
        Err(_) => {
            inst.log.log(
                Status::Fatal,
                crate::log::ERROR,
                &format!("{call}: internal error in the FMU (a bug in Tribo; please report it)"),
            );
            FATAL
        }
    }
}

/// An FMI function defined by `body` over the instance pointer `c` and the other arguments,
/// with the safety contract every one of them has.
macro_rules! fmi_function {
    ($(#[$doc:meta])* $name:ident($c:ident $(, $arg:ident: $ty:ty)*) => $body:expr) => {
        $(#[$doc])*
        ///
        /// # Safety
        /// `c` from fmi2Instantiate; the other arguments as FMI 2.0 defines them.
        #[no_mangle]
        pub unsafe extern "C" fn $name($c: Component $(, $arg: $ty)*) -> Fmi2Status {
            $body
        }
    };
}

/// The platform of the FMU's types.
#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

/// The FMI version.
#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

/// Create an instance: read the resources, check the GUID, start the worker. NULL (with a
/// logged message) if any of that fails.
///
/// # Safety
/// Arguments as FMI 2.0 defines them: valid C strings (or NULL) and a valid callback struct.
#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instance_name: *const c_char,
    fmu_type: c_int,
    fmu_guid: *const c_char,
    resource_location: *const c_char,
    functions: *const CallbackFunctions,
    _visible: c_int,
    logging_on: c_int,
) -> Component {
    let result = catch_unwind(AssertUnwindSafe(|| {
        // SAFETY: the importer's strings and callbacks, valid per the FMI contract.
        let name = unsafe { text(instance_name) }.unwrap_or("tribo");
        let log = unsafe { Logger::new(functions, name, logging_on != 0) };
        let fail = |log: &Logger, m: String| {
            log.error(&format!("fmi2Instantiate: {m}"));
            std::ptr::null_mut()
        };
        if fmu_type != CO_SIMULATION {
            return fail(
                &log,
                "this FMU is for Co-Simulation only, not Model Exchange".into(),
            );
        }
        let Some(location) = (unsafe { text(resource_location) }) else {
            return fail(
                &log,
                "no resource location was given; the FMU needs its resources directory".into(),
            );
        };
        let dir = match crate::uri::resource_dir(location) {
            Ok(d) => d,
            Err(e) => return fail(&log, e),
        };
        let iface = match crate::worker::read_interface(&dir) {
            Ok(i) => i,
            Err(e) => return fail(&log, e.to_string()),
        };
        let guid = unsafe { text(fmu_guid) }.unwrap_or("");
        if guid != iface.guid {
            return fail(
                &log,
                format!(
                    "the GUID {guid} is not this FMU's ({}): the modelDescription.xml and the resources come from different exports",
                    iface.guid
                ),
            );
        }
        let mut inst = Instance::new(log, dir, iface);
        if let Err(e) = inst.spawn() {
            return fail(&inst.log, e);
        }
        Box::into_raw(Box::new(inst)).cast::<c_void>()
    }));
    result.unwrap_or(std::ptr::null_mut())
}

/// Free an instance (its worker is stopped).
///
/// # Safety
/// `c` must come from fmi2Instantiate and not be used again.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: Component) {
    if !c.is_null() {
        let _ = catch_unwind(|| {
            // SAFETY: `c` is a Box<Instance> from fmi2Instantiate, freed once.
            drop(unsafe { Box::from_raw(c.cast::<Instance>()) });
        });
    }
}

/// Turn debug logging (informational messages) on or off.
///
/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: Component,
    logging_on: c_int,
    _n_categories: usize,
    _categories: *const *const c_char,
) -> Fmi2Status {
    with(c, "fmi2SetDebugLogging", |i| {
        i.log.debug = logging_on != 0;
        Ok(())
    })
}

/// Set the start time (tolerance and stop time are not needed: the solver has its own).
///
/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: Component,
    _tolerance_defined: c_int,
    _tolerance: f64,
    start_time: f64,
    _stop_time_defined: c_int,
    _stop_time: f64,
) -> Fmi2Status {
    with(c, "fmi2SetupExperiment", |i| i.setup_experiment(start_time))
}

/// Enter initialisation mode.
///
/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: Component) -> Fmi2Status {
    with(
        c,
        "fmi2EnterInitializationMode",
        Instance::enter_initialization,
    )
}

/// Leave initialisation mode: the run is built.
///
/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: Component) -> Fmi2Status {
    with(
        c,
        "fmi2ExitInitializationMode",
        Instance::exit_initialization,
    )
}

/// End the simulation.
///
/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: Component) -> Fmi2Status {
    with(c, "fmi2Terminate", Instance::terminate)
}

/// Back to the state after instantiation.
///
/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: Component) -> Fmi2Status {
    with(c, "fmi2Reset", Instance::reset)
}

/// Read `n` values of type `ty` into `out` through `put`.
///
/// # Safety
/// `vr` and `out` must hold `n` elements.
unsafe fn get<T>(
    c: Component,
    call: &str,
    ty: &str,
    vr: *const ValueReference,
    n: usize,
    out: *mut T,
    put: impl Fn(Value) -> Option<T>,
) -> Fmi2Status {
    with(c, call, |i| {
        // SAFETY: the importer passes `n` value references.
        let vrs = unsafe { slice(vr, n) }.ok_or("NULL value-reference array")?;
        if n > 0 && out.is_null() {
            return Err("NULL value array".into());
        }
        let values = i.get(vrs, ty)?;
        for (k, v) in values.into_iter().enumerate() {
            let x = put(v).ok_or("a value of another type")?;
            // SAFETY: `out` holds `n` elements, k < n.
            unsafe { out.add(k).write(x) };
        }
        Ok(())
    })
}

/// Write `n` values of type `ty` from `values` through `take`.
///
/// # Safety
/// `vr` and `values` must hold `n` elements.
unsafe fn set<T: Copy>(
    c: Component,
    call: &str,
    ty: &str,
    vr: *const ValueReference,
    n: usize,
    values: *const T,
    take: impl Fn(T) -> Value,
) -> Fmi2Status {
    with(c, call, |i| {
        // SAFETY: the importer passes `n` value references and values.
        let vrs = unsafe { slice(vr, n) }.ok_or("NULL value-reference array")?;
        let xs = unsafe { slice(values, n) }.ok_or("NULL value array")?;
        let xs: Vec<Value> = xs.iter().map(|x| take(*x)).collect();
        i.set(vrs, &xs, ty)
    })
}

fmi_function!(
    /// fmi2GetReal.
    fmi2GetReal(c, vr: *const ValueReference, nvr: usize, value: *mut f64)
    => unsafe { get(c, "fmi2GetReal", "Real", vr, nvr, value, |v| match v {
        Value::Real(x) => Some(x),
        _ => None,
    }) }
);

fmi_function!(
    /// fmi2GetInteger (the enumerations).
    fmi2GetInteger(c, vr: *const ValueReference, nvr: usize, value: *mut c_int)
    => unsafe { get(c, "fmi2GetInteger", "Integer", vr, nvr, value, |v| match v {
        Value::Int(x) => Some(x),
        _ => None,
    }) }
);

fmi_function!(
    /// fmi2GetBoolean.
    fmi2GetBoolean(c, vr: *const ValueReference, nvr: usize, value: *mut c_int)
    => unsafe { get(c, "fmi2GetBoolean", "Boolean", vr, nvr, value, |v| match v {
        Value::Bool(b) => Some(c_int::from(b)),
        _ => None,
    }) }
);

fmi_function!(
    /// fmi2SetReal.
    fmi2SetReal(c, vr: *const ValueReference, nvr: usize, value: *const f64)
    => unsafe { set(c, "fmi2SetReal", "Real", vr, nvr, value, Value::Real) }
);

fmi_function!(
    /// fmi2SetInteger (the enumerations).
    fmi2SetInteger(c, vr: *const ValueReference, nvr: usize, value: *const c_int)
    => unsafe { set(c, "fmi2SetInteger", "Integer", vr, nvr, value, Value::Int) }
);

fmi_function!(
    /// fmi2SetBoolean.
    fmi2SetBoolean(c, vr: *const ValueReference, nvr: usize, value: *const c_int)
    => unsafe { set(c, "fmi2SetBoolean", "Boolean", vr, nvr, value, |b| Value::Bool(b != 0)) }
);

/// The string calls of an FMU without String variables: nothing to read or write.
fn no_strings(nvr: usize) -> CallResult<()> {
    if nvr == 0 {
        Ok(())
    } else {
        Err("this FMU has no String variables".into())
    }
}

fmi_function!(
    /// fmi2GetString: the FMU has no String variables.
    fmi2GetString(c, _vr: *const ValueReference, nvr: usize, _value: *mut *const c_char)
    => with(c, "fmi2GetString", |_| no_strings(nvr))
);

fmi_function!(
    /// fmi2SetString: the FMU has no String variables.
    fmi2SetString(c, _vr: *const ValueReference, nvr: usize, _value: *const *const c_char)
    => with(c, "fmi2SetString", |_| no_strings(nvr))
);

/// fmi2GetFMUstate: the whole state (the worker's run, laws' states included), new or into
/// the state `*state` points to.
///
/// # Safety
/// `state` must be a valid pointer to NULL or to a state from this FMU.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: Component, state: *mut FmuState) -> Fmi2Status {
    with(c, "fmi2GetFMUstate", |i| {
        if state.is_null() {
            return Err("NULL state pointer".into());
        }
        let saved = i.save()?;
        // SAFETY: `state` is valid; a non-NULL `*state` is a Box<Saved> of this FMU.
        unsafe {
            let old = *state;
            if old.is_null() {
                *state = Box::into_raw(Box::new(saved)).cast();
            } else {
                *old.cast::<Saved>() = saved;
            }
        }
        Ok(())
    })
}

/// fmi2SetFMUstate.
///
/// # Safety
/// `state` from fmi2GetFMUstate or fmi2DeSerializeFMUstate of this FMU.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: Component, state: FmuState) -> Fmi2Status {
    with(c, "fmi2SetFMUstate", |i| {
        // SAFETY: a Box<Saved> of this FMU, or NULL.
        let saved = unsafe { state.cast::<Saved>().as_ref() }.ok_or("NULL state")?;
        i.restore(saved)
    })
}

/// fmi2FreeFMUstate.
///
/// # Safety
/// `state` points to NULL or a state of this FMU, freed once.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: Component, state: *mut FmuState) -> Fmi2Status {
    with(c, "fmi2FreeFMUstate", |_| {
        if state.is_null() {
            return Ok(());
        }
        // SAFETY: `*state` is NULL or a Box<Saved> made here.
        unsafe {
            let s = *state;
            if !s.is_null() {
                drop(Box::from_raw(s.cast::<Saved>()));
            }
            *state = std::ptr::null_mut();
        }
        Ok(())
    })
}

/// fmi2SerializedFMUstateSize.
///
/// # Safety
/// `state` a state of this FMU; `size` valid.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: Component,
    state: FmuState,
    size: *mut usize,
) -> Fmi2Status {
    with(c, "fmi2SerializedFMUstateSize", |_| {
        // SAFETY: as documented.
        let saved = unsafe { state.cast::<Saved>().as_ref() }.ok_or("NULL state")?;
        if size.is_null() {
            return Err("NULL size pointer".into());
        }
        unsafe { *size = serialize(saved).len() };
        Ok(())
    })
}

/// fmi2SerializeFMUstate.
///
/// # Safety
/// `state` a state of this FMU; `bytes` holds `size` bytes.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: Component,
    state: FmuState,
    bytes: *mut c_char,
    size: usize,
) -> Fmi2Status {
    with(c, "fmi2SerializeFMUstate", |_| {
        // SAFETY: as documented.
        let saved = unsafe { state.cast::<Saved>().as_ref() }.ok_or("NULL state")?;
        let data = serialize(saved);
        if bytes.is_null() || size < data.len() {
            return Err(format!(
                "the buffer of {size} bytes is smaller than the state's {}",
                data.len()
            ));
        }
        // SAFETY: `bytes` holds at least `data.len()` bytes.
        unsafe { std::ptr::copy_nonoverlapping(data.as_ptr(), bytes.cast::<u8>(), data.len()) };
        Ok(())
    })
}

/// fmi2DeSerializeFMUstate.
///
/// # Safety
/// `bytes` holds `size` bytes; `state` valid.
#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: Component,
    bytes: *const c_char,
    size: usize,
    state: *mut FmuState,
) -> Fmi2Status {
    with(c, "fmi2DeSerializeFMUstate", |_| {
        // SAFETY: as documented.
        let data = unsafe { slice(bytes.cast::<u8>(), size) }.ok_or("NULL bytes")?;
        if state.is_null() {
            return Err("NULL state pointer".into());
        }
        let saved = deserialize(data)?;
        unsafe { *state = Box::into_raw(Box::new(saved)).cast() };
        Ok(())
    })
}

fmi_function!(
    /// fmi2GetDirectionalDerivative: not provided (the description says so).
    fmi2GetDirectionalDerivative(c, _unknown: *const ValueReference, _n_unknown: usize,
        _known: *const ValueReference, _n_known: usize, _dv_known: *const f64,
        _dv_unknown: *mut f64)
    => with(c, "fmi2GetDirectionalDerivative", |_| {
        Err("this FMU provides no directional derivatives".into())
    })
);

fmi_function!(
    /// fmi2SetRealInputDerivatives: inputs are held constant over a step
    /// (canInterpolateInputs is false).
    fmi2SetRealInputDerivatives(c, _vr: *const ValueReference, _nvr: usize,
        _order: *const c_int, _value: *const f64)
    => with(c, "fmi2SetRealInputDerivatives", |_| {
        Err("this FMU holds its inputs constant over a step (canInterpolateInputs=false)".into())
    })
);

fmi_function!(
    /// fmi2GetRealOutputDerivatives: not provided (maxOutputDerivativeOrder is 0).
    fmi2GetRealOutputDerivatives(c, _vr: *const ValueReference, _nvr: usize,
        _order: *const c_int, _value: *mut f64)
    => with(c, "fmi2GetRealOutputDerivatives", |_| {
        Err("this FMU provides no output derivatives (maxOutputDerivativeOrder=0)".into())
    })
);

/// fmi2DoStep: integrate over the communication step, any size.
///
/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(
    c: Component,
    current: f64,
    step: f64,
    _no_set_prior: c_int,
) -> Fmi2Status {
    with(c, "fmi2DoStep", |i| i.do_step(current, step))
}

fmi_function!(
    /// fmi2CancelStep: steps are synchronous, there is nothing to cancel.
    fmi2CancelStep(c)
    => with(c, "fmi2CancelStep", |_| {
        Err("steps are synchronous (canRunAsynchronuously=false); there is nothing to cancel".into())
    })
);

fmi_function!(
    /// fmi2GetStatus: only asked of asynchronous steps, which this FMU does not run.
    fmi2GetStatus(c, _kind: c_int, _value: *mut c_int) => status_discard(c)
);

/// fmi2LastSuccessfulTime, the one real status.
const LAST_SUCCESSFUL_TIME: c_int = 2;
/// fmi2Terminated, the one boolean status.
const TERMINATED: c_int = 4;

/// Answer a status query of kind `kind` with `read(instance)` when it is the `known` kind;
/// discard any other.
///
/// # Safety
/// `c` from fmi2Instantiate; `value` NULL or valid.
unsafe fn status<T>(
    c: Component,
    kind: c_int,
    known: c_int,
    value: *mut T,
    read: impl FnOnce(&Instance) -> T,
) -> Fmi2Status {
    if c.is_null() || value.is_null() || kind != known {
        return DISCARD;
    }
    // SAFETY: a live instance and a valid pointer, by the caller's contract.
    unsafe { *value = read(&*c.cast::<Instance>()) };
    OK
}

fmi_function!(
    /// fmi2GetRealStatus: the last successful time (fmi2LastSuccessfulTime), else discarded.
    fmi2GetRealStatus(c, kind: c_int, value: *mut f64)
    => unsafe { status(c, kind, LAST_SUCCESSFUL_TIME, value, Instance::time) }
);

fmi_function!(
    /// fmi2GetIntegerStatus: nothing to report.
    fmi2GetIntegerStatus(c, _kind: c_int, _value: *mut c_int) => status_discard(c)
);

fmi_function!(
    /// fmi2GetBooleanStatus: fmi2Terminated is false (the FMU never ends a simulation itself).
    fmi2GetBooleanStatus(c, kind: c_int, value: *mut c_int)
    => unsafe { status(c, kind, TERMINATED, value, |_| 0) }
);

fmi_function!(
    /// fmi2GetStringStatus: nothing to report.
    fmi2GetStringStatus(c, _kind: c_int, _value: *mut *const c_char) => status_discard(c)
);

fn status_discard(c: Component) -> Fmi2Status {
    if c.is_null() {
        ERROR
    } else {
        DISCARD
    }
}
