//! Messages to the importer through the FMI logger callback.

use std::ffi::{c_char, c_int, c_void, CString};

/// The log categories the FMU declares and uses.
pub const CATEGORIES: [(&str, &str); 3] = [
    (
        ERROR,
        "errors: a missing or corrupt resource, a refused input or parameter, a failed step, a law that crashed or hung",
    ),
    (WARNING, "warnings"),
    (INFO, "progress: the worker process started"),
];

/// Category of error messages.
pub const ERROR: &str = "logStatusError";
/// Category of warnings.
pub const WARNING: &str = "logStatusWarning";
/// Category of informational messages (only with debug logging on).
pub const INFO: &str = "logAll";

/// fmi2Status.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
#[repr(i32)]
pub enum Status {
    /// fmi2OK.
    Ok = 0,
    /// fmi2Warning.
    Warning = 1,
    /// fmi2Discard.
    Discard = 2,
    /// fmi2Error.
    Error = 3,
    /// fmi2Fatal.
    Fatal = 4,
}

/// fmi2CallbackLogger: printf-style (the message is a format string).
pub type LoggerFn = unsafe extern "C" fn(
    env: *mut c_void,
    instance_name: *const c_char,
    status: c_int,
    category: *const c_char,
    message: *const c_char,
    ...
);

/// fmi2CallbackFunctions, as the importer hands it to fmi2Instantiate.
#[repr(C)]
pub struct CallbackFunctions {
    /// The logger.
    pub logger: Option<LoggerFn>,
    /// fmi2CallbackAllocateMemory (not used: the FMU allocates its own memory).
    pub allocate_memory: Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>,
    /// fmi2CallbackFreeMemory (not used).
    pub free_memory: Option<unsafe extern "C" fn(*mut c_void)>,
    /// fmi2StepFinished (not used: steps are synchronous).
    pub step_finished: Option<unsafe extern "C" fn(*mut c_void, c_int)>,
    /// The importer's pointer handed back with every callback.
    pub component_environment: *mut c_void,
}

/// The importer's logger for one instance.
pub struct Logger {
    logger: Option<LoggerFn>,
    env: *mut c_void,
    name: CString,
    /// Whether informational messages are wanted (fmi2SetDebugLogging / loggingOn).
    pub debug: bool,
}

/// `text` as a C string: interior NULs replaced.
pub fn c_text(text: &str) -> CString {
    CString::new(text.replace('\0', " ")).unwrap_or_default()
}

impl Logger {
    /// The logger of `callbacks` (may be NULL) for the instance `name`.
    ///
    /// # Safety
    /// `callbacks` must be NULL or point to a valid `fmi2CallbackFunctions`.
    pub unsafe fn new(callbacks: *const CallbackFunctions, name: &str, debug: bool) -> Self {
        // SAFETY: the caller guarantees the pointer is NULL or valid.
        let (logger, env) = match unsafe { callbacks.as_ref() } {
            Some(c) => (c.logger, c.component_environment),
            None => (None, std::ptr::null_mut()),
        };
        Self {
            logger,
            env,
            name: c_text(name),
            debug,
        }
    }

    /// Log `message` with `status` in `category`. Errors and warnings always reach the
    /// importer; informational messages only with debug logging on.
    pub fn log(&self, status: Status, category: &str, message: &str) {
        if status == Status::Ok && !self.debug {
            return;
        }
        let Some(logger) = self.logger else {
            return;
        };
        // The message is a printf format: a literal percent sign is written as two.
        let message = c_text(&message.replace('%', "%%"));
        let category = c_text(category);
        // SAFETY: the importer's logger, called with its own environment pointer and valid C
        // strings that outlive the call; the format has no conversions.
        unsafe {
            logger(
                self.env,
                self.name.as_ptr(),
                status as c_int,
                category.as_ptr(),
                message.as_ptr(),
            );
        }
    }

    /// Log an error.
    pub fn error(&self, message: &str) {
        self.log(Status::Error, ERROR, message);
    }

    /// Log an informational message (debug logging only).
    pub fn info(&self, message: &str) {
        self.log(Status::Ok, INFO, message);
    }
}
