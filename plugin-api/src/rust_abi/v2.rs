//! The Rust plugin ABI of contract version 2, frozen: what a library built against version 2
//! exports, so the host can still load it (`loader/rust.rs`).
//!
//! abi_stable checks a library's root module against the host's type by layout, field names,
//! type names and crate name (`tribo-plugin-api`, version 0.1.x). So every item here keeps the
//! name and shape it had in version 2: [`LawModule`], [`RLawObject`], the input
//! [`LawInput`](crate::contract::v2::LawInput) and the output
//! [`LawOutput`](crate::contract::v2::LawOutput). The parts no version changed
//! ([`RLawDescription`](super::RLawDescription), [`RCreateError`](super::RCreateError)) are
//! shared with the current module. Nothing here may change again: a version-2 library in the
//! field was built from exactly this.

// As in the parent module: abi_stable's `sabi_trait` expansion, not ours.
#![allow(non_local_definitions)]

use abi_stable::library::RootModule;
use abi_stable::prefix_type::PrefixTypeTrait;
use abi_stable::sabi_trait;
use abi_stable::sabi_types::VersionStrings;
use abi_stable::std_types::{RBox, RResult, RSlice, RSliceMut, RStr, RString};
use abi_stable::StableAbi;

use super::{create_adapter, describe_shim, Adapter, RCreateError, RLawDescription};
use crate::contract::v2::{LawInput, LawOutput};
use crate::law::Law;

/// Contract version 2 as abi_stable's semver string.
pub const CONTRACT_VERSION_STRING: &str = "2.0.0";

/// A version-2 law instance across the boundary: evaluate returns its output by value.
#[sabi_trait]
pub trait RLawObject: Send + Sync {
    /// Number of state variables.
    fn state_size(&self) -> usize;

    /// Evaluate; `Err` carries a panic message.
    fn evaluate(&self, input: &LawInput, state: RSlice<'_, f64>) -> RResult<LawOutput, RString>;

    /// Commit an accepted step; `Err` carries a panic message.
    #[sabi(last_prefix_field)]
    fn commit(&self, input: &LawInput, state: RSliceMut<'_, f64>) -> RResult<(), RString>;
}

/// Boxed, type-erased version-2 law instance.
pub type RLawBox = RLawObject_TO<'static, RBox<()>>;

/// The root module a version-2 library exports.
#[repr(C)]
#[derive(StableAbi)]
#[sabi(kind(Prefix(prefix_ref = LawModuleRef)))]
#[sabi(missing_field(panic))]
pub struct LawModule {
    /// Always 2.
    pub contract_version: u32,
    /// Describe the law.
    pub describe: extern "C" fn() -> RResult<RLawDescription, RCreateError>,
    /// Create an instance from parameters given as TOML text.
    #[sabi(last_prefix_field)]
    pub create: extern "C" fn(RStr<'_>) -> RResult<RLawBox, RCreateError>,
}

impl RootModule for LawModuleRef {
    abi_stable::declare_root_module_statics! {LawModuleRef}
    const BASE_NAME: &'static str = "tribo_law";
    const NAME: &'static str = "tribo_law";
    const VERSION_STRINGS: VersionStrings = VersionStrings::new(CONTRACT_VERSION_STRING);
}

impl<L: Law> RLawObject for Adapter<L> {
    fn state_size(&self) -> usize {
        self.state_size
    }

    fn evaluate(&self, input: &LawInput, state: RSlice<'_, f64>) -> RResult<LawOutput, RString> {
        self.evaluate_frozen(&input.into(), state.as_slice())
    }

    fn commit(&self, input: &LawInput, mut state: RSliceMut<'_, f64>) -> RResult<(), RString> {
        self.commit_caught(&input.into(), state.as_mut_slice())
    }
}

extern "C" fn create_shim<L: Law>(params_toml: RStr<'_>) -> RResult<RLawBox, RCreateError> {
    create_adapter::<L>(params_toml)
        .map(|a| RLawObject_TO::from_value(a, abi_stable::sabi_trait::TD_Opaque))
        .into()
}

/// The version-2 root module for law `L`: only for the test fixture that stands for a library
/// built against version 2 (`tests/fixtures/rust-probe-v2`).
#[doc(hidden)]
pub fn module_for<L: Law>() -> LawModuleRef {
    LawModule {
        contract_version: 2,
        describe: describe_shim::<L>,
        create: create_shim::<L>,
    }
    .leak_into_prefix()
}

/// Export law `L` as a version-2 library would: the version symbol returns 2 and the root
/// module is the frozen [`LawModule`]. Only for the compatibility test fixture.
#[doc(hidden)]
#[macro_export]
macro_rules! __export_law_v2 {
    ($law:ty) => {
        $crate::__export_law_module!(
            2,
            $crate::rust_abi::v2::LawModuleRef,
            $crate::rust_abi::v2::module_for::<$law>()
        );
    };
}
