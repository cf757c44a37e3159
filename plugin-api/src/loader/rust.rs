//! Loading Rust law libraries through abi_stable's library header (one header per file, so any
//! number of law libraries can be loaded side by side).

use std::path::Path;

use abi_stable::library::{lib_header_from_path, ROOT_MODULE_LOADER_NAME_WITH_NUL};
use abi_stable::std_types::{RResult, RStr};

use super::{InstBackend, LawError, LawLibrary};
use crate::describe::{LawDescription, ParamError};
use crate::rust_abi::{from_r_description, v1, v2, LawModuleRef, RCreateError, RLawDescription};

/// True if `lib` exports an abi_stable library header (a Rust plugin).
pub(super) fn exports_rust_module(lib: &libloading::Library) -> bool {
    // SAFETY: only the symbol's presence is tested; it is not dereferenced here.
    unsafe { lib.get::<*const u8>(ROOT_MODULE_LOADER_NAME_WITH_NUL.as_bytes()) }.is_ok()
}

/// A Rust law library whose module passed abi_stable's version and layout checks: built
/// against the current contract or against a frozen older one.
pub(super) enum RustLib {
    Current(LawModuleRef),
    V2(v2::LawModuleRef),
    V1(v1::LawModuleRef),
}

impl RustLib {
    /// Load the module of `path`, whose version symbol said `version` (already checked to be
    /// one the host speaks).
    pub(super) fn load(path: &Path, version: u32) -> Result<Self, LawError> {
        let abi_err = |e: abi_stable::library::LibraryError| LawError::AbiCheck {
            path: path.to_path_buf(),
            detail: e.to_string(),
        };
        let header = lib_header_from_path(path).map_err(abi_err)?;
        let (lib, found) = match version {
            1 => {
                let module = header
                    .init_root_module::<v1::LawModuleRef>()
                    .map_err(abi_err)?;
                (Self::V1(module), module.contract_version())
            }
            2 => {
                let module = header
                    .init_root_module::<v2::LawModuleRef>()
                    .map_err(abi_err)?;
                (Self::V2(module), module.contract_version())
            }
            _ => {
                let module = header.init_root_module::<LawModuleRef>().map_err(abi_err)?;
                (Self::Current(module), module.contract_version())
            }
        };
        // The module's own version must agree with the symbol the loader read first.
        if found != version {
            return Err(LawError::ContractMismatch {
                path: path.to_path_buf(),
                found,
                expected: crate::CONTRACT_VERSION,
                oldest: crate::contract::OLDEST_CONTRACT_VERSION,
            });
        }
        Ok(lib)
    }

    fn describe_fn(&self) -> extern "C" fn() -> RResult<RLawDescription, RCreateError> {
        match self {
            Self::Current(m) => m.describe(),
            Self::V2(m) => m.describe(),
            Self::V1(m) => m.describe(),
        }
    }

    /// The `SUITS_*` bits the law declares (a library older than version 3 cannot: 0, any).
    pub(super) fn suits(&self) -> u32 {
        match self {
            Self::Current(m) => m.suits(),
            Self::V2(_) | Self::V1(_) => 0,
        }
    }

    pub(super) fn describe(&self, path: &Path) -> Result<LawDescription, LawError> {
        let bad = |detail: String| LawError::BadDescription {
            path: path.to_path_buf(),
            detail,
        };
        match (self.describe_fn())() {
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

    pub(super) fn create(
        &self,
        params_toml: &str,
        lib: &LawLibrary,
    ) -> Result<InstBackend, LawError> {
        let params = RStr::from_str(params_toml);
        let created = match self {
            Self::Current(m) => (m.create())(params).map(InstBackend::Rust),
            Self::V2(m) => (m.create())(params).map(InstBackend::RustV2),
            Self::V1(m) => (m.create())(params).map(InstBackend::RustV1),
        };
        match created {
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
