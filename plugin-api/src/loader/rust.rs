//! Loading Rust law libraries through abi_stable's library header (one header per file, so any
//! number of law libraries can be loaded side by side).

use std::path::Path;

use abi_stable::library::{lib_header_from_path, ROOT_MODULE_LOADER_NAME_WITH_NUL};
use abi_stable::std_types::{RResult, RStr};

use super::{LawError, LawLibrary};
use crate::describe::{LawDescription, ParamError};
use crate::rust_abi::{from_r_description, LawModuleRef, RLawBox};

/// True if `lib` exports an abi_stable library header (a Rust plugin).
pub(super) fn exports_rust_module(lib: &libloading::Library) -> bool {
    // SAFETY: only the symbol's presence is tested; it is not dereferenced here.
    unsafe { lib.get::<*const u8>(ROOT_MODULE_LOADER_NAME_WITH_NUL.as_bytes()) }.is_ok()
}

/// A Rust law library whose module passed abi_stable's version and layout checks.
pub(super) struct RustLib {
    module: LawModuleRef,
}

impl RustLib {
    pub(super) fn load(path: &Path) -> Result<Self, LawError> {
        let abi_err = |e: abi_stable::library::LibraryError| LawError::AbiCheck {
            path: path.to_path_buf(),
            detail: e.to_string(),
        };
        let header = lib_header_from_path(path).map_err(abi_err)?;
        let module = header.init_root_module::<LawModuleRef>().map_err(abi_err)?;
        let found = module.contract_version();
        if found != crate::CONTRACT_VERSION {
            return Err(LawError::ContractMismatch {
                path: path.to_path_buf(),
                found,
                expected: crate::CONTRACT_VERSION,
            });
        }
        Ok(Self { module })
    }

    pub(super) fn describe(&self, path: &Path) -> Result<LawDescription, LawError> {
        let bad = |detail: String| LawError::BadDescription {
            path: path.to_path_buf(),
            detail,
        };
        match (self.module.describe())() {
            RResult::ROk(d) => from_r_description(&d).map_err(bad),
            RResult::RErr(e) => Err(bad(format!(
                "{}{}{}",
                if e.panicked { "panicked: " } else { "" },
                if e.parameter.is_empty() {
                    String::new()
                } else {
                    format!("parameter `{}`: ", e.parameter)
                },
                e.message
            ))),
        }
    }

    pub(super) fn create(&self, params_toml: &str, lib: &LawLibrary) -> Result<RLawBox, LawError> {
        match (self.module.create())(RStr::from_str(params_toml)) {
            RResult::ROk(obj) => Ok(obj),
            RResult::RErr(e) if e.panicked => {
                Err(lib.failed("create", format!("panicked: {}", e.message)))
            }
            RResult::RErr(e) => Err(lib.param_error(
                ParamError::new(e.parameter.as_str(), e.message.as_str()).for_law(lib.name()),
            )),
        }
    }
}
