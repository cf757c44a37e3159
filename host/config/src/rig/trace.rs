//! A cylinder-pressure trace given as a CSV file next to the rig or bundled.

use std::path::PathBuf;

use super::{CylinderPressure, Rig, RigError};
use crate::files::read_text;

/// Fill a cylinder-pressure `trace` given by `file` from that CSV: next to the rig file (or
/// any file of its `extends` chain, child first), else a bundled data file. A row is
/// `crank_angle_deg,pressure_pa`; a first row that is not numbers is a header; `#` starts a
/// comment. A bad row is an error at the CSV's line and column; columns given beside `file`
/// that differ from the file's are refused (they would be overwritten unread).
pub(super) fn read_trace_file(rig: &mut Rig) -> Result<(), RigError> {
    let name = match &rig.file.gas.cylinder {
        CylinderPressure::Trace {
            file: Some(name), ..
        } => name.clone(),
        _ => return Ok(()),
    };
    let field = "gas.cylinder.file";
    let mut found: Option<(PathBuf, String)> = None;
    for src in &rig.sources {
        let Some(dir) = src.path.parent() else {
            continue;
        };
        if src.path.starts_with("<bundled>") {
            continue;
        }
        let path = dir.join(&name);
        match read_text(&path) {
            Ok(text) => {
                found = Some((path, text));
                break;
            }
            Err(e) if e.is_not_found() => {}
            Err(e) => return Err(rig.error(field, format!("{}: {e}", path.display()))),
        }
    }
    if found.is_none() {
        found = crate::bundled::data(&name)
            .map(|t| (PathBuf::from(format!("<bundled>/{name}")), t.to_string()));
    }
    let Some((path, text)) = found else {
        return Err(rig.error(
            field,
            format!("pressure trace `{name}` not found next to the rig file nor among the bundled data ({})", crate::bundled::data_names().join(", ")),
        ));
    };
    let (angles, pressures) = parse_trace(&text).map_err(|(line, col, msg)| {
        rig.error(field, format!("{}:{line}:{col}: {msg}", path.display()))
    })?;
    if let CylinderPressure::Trace {
        crank_angle_deg,
        pressure_pa,
        ..
    } = &rig.file.gas.cylinder
    {
        for (column, given, read) in [
            ("crank_angle_deg", crank_angle_deg, &angles),
            ("pressure_pa", pressure_pa, &pressures),
        ] {
            // A column given beside `file` would be overwritten unread; one equal to the file's
            // (a loaded rig written back out, as an FMU's model) is the same trace.
            if !given.is_empty() && given != read {
                return Err(rig.error(
                    &format!("gas.cylinder.{column}"),
                    format!("the trace is read from `file` (`{name}`): give its columns there or here without `file`, not both"),
                ));
            }
        }
    }
    if let CylinderPressure::Trace {
        crank_angle_deg,
        pressure_pa,
        ..
    } = &mut rig.file.gas.cylinder
    {
        *crank_angle_deg = angles;
        *pressure_pa = pressures;
    }
    Ok(())
}

/// A bad row of a pressure trace: line, column (1-based) and what is wrong.
type TraceError = (usize, usize, String);

/// Parse a pressure trace CSV into angles and pressures, or `(line, column, message)`.
fn parse_trace(text: &str) -> Result<(Vec<f64>, Vec<f64>), TraceError> {
    let (mut angles, mut pressures) = (Vec::new(), Vec::new());
    let mut header_allowed = true;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("");
        if line.trim().is_empty() {
            continue;
        }
        let cells: Vec<&str> = line.split(',').collect();
        if cells.len() != 2 {
            return Err((
                i + 1,
                1,
                format!(
                    "expected two columns `crank_angle_deg,pressure_pa`, found {}",
                    cells.len()
                ),
            ));
        }
        let first = cells[0].trim().parse::<f64>();
        if first.is_err() && header_allowed {
            header_allowed = false;
            continue;
        }
        header_allowed = false;
        let mut values = [0.0; 2];
        let mut col = 1;
        for (k, cell) in cells.iter().enumerate() {
            let what = ["crank angle (degrees)", "pressure (Pa)"][k];
            let lead = cell.len() - cell.trim_start().len();
            values[k] = cell.trim().parse::<f64>().map_err(|_| {
                (
                    i + 1,
                    col + lead,
                    format!("expected a number, the {what}, got `{}`", cell.trim()),
                )
            })?;
            col += cell.len() + 1;
        }
        angles.push(values[0]);
        pressures.push(values[1]);
    }
    Ok((angles, pressures))
}
