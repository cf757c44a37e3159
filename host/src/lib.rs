//! # tribo (host)
//!
//! The Tribo host: the command-line tool and the pieces behind it. Laws are never linked in;
//! they are found and loaded through `tribo_plugin_api::loader`.
//!
//! - [`laws`]: listing of discovered laws (`tribo laws`);
//! - [`scaffold`]: generation of a new law crate (`tribo new-law`);
//! - [`mechanics`]: planar rigid multibody model of the rig (positions to joint reactions).

pub mod laws;
pub mod mechanics;
pub mod scaffold;

pub use tribo_plugin_api as plugin_api;
