//! `--oil FILE.toml`: an oil described in its own file, turned into `--set` overrides.

use std::path::Path;

use tribo_core::oil::ViscosityModel;

use super::error::{file_error, serde_error};
use super::RigError;
use crate::files::read_text;

/// Keys an oil file's `[oil]` table may hold: what describes the oil itself (temperatures
/// belong to the rig's cycle or to the sweep).
pub const OIL_FILE_KEYS: [&str; 5] = ["name", "grade", "source", "viscosity", "density_kg_m3"];

/// Read an oil file (`--oil FILE.toml`: an `[oil]` table with any of [`OIL_FILE_KEYS`]) and turn
/// it into `--set oil.KEY=VALUE` overrides, to be applied before the user's own `--set`s. The
/// file is checked here, so its mistakes are reported at its own line and column: unknown keys,
/// and a viscosity model that does not parse.
pub fn oil_file_sets(path: &Path) -> Result<Vec<String>, RigError> {
    let err = |text: &str, field: &str, message: String| RigError::at(path, text, field, message);
    let text = read_text(path).map_err(|e| file_error(path, "oil file", &e))?;
    let table: toml::Table = toml::from_str(&text).map_err(|e| serde_error(path, &text, &e, ""))?;
    if let Some(k) = table.keys().find(|k| *k != "oil") {
        return Err(err(
            &text,
            k,
            format!("unknown key `{k}`: an oil file holds one `[oil]` table"),
        ));
    }
    let oil = match table.get("oil") {
        Some(toml::Value::Table(t)) => t,
        _ => return Err(err(&text, "oil", "expected an `[oil]` table".into())),
    };
    let mut sets = Vec::new();
    for (k, v) in oil {
        if !OIL_FILE_KEYS.contains(&k.as_str()) {
            return Err(err(
                &text,
                &format!("oil.{k}"),
                format!(
                    "unknown field `{k}`, expected one of {}",
                    OIL_FILE_KEYS.join(", ")
                ),
            ));
        }
        if k == "viscosity" {
            v.clone()
                .try_into::<ViscosityModel>()
                .map_err(|e| err(&text, "oil.viscosity", e.message().to_string()))?;
        }
        sets.push(format!("oil.{k}={v}"));
    }
    Ok(sets)
}
