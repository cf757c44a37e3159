//! Reading a rig: the `extends` chain merged child over base, `--set` overrides applied, the
//! result deserialised with errors located in the file that gives the field.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::error::{field_error, file_error, locate_key, serde_error};
use super::trace::read_trace_file;
use super::validate::validate;
use super::{Rig, RigError, RigFile, Source};
use crate::files::{read_text, ReadError};

/// Parse `KEY=VALUE` overrides into the table; VALUE is read as TOML, or as a string if it is
/// not valid TOML.
fn apply_set(table: &mut toml::Table, assignment: &str) -> Result<String, RigError> {
    let err = |field: &str, message: String| RigError {
        file: PathBuf::from("--set"),
        line: None,
        column: None,
        field: field.into(),
        message,
    };
    let (key, value) = assignment.split_once('=').ok_or_else(|| {
        err(
            assignment,
            "expected KEY=VALUE, e.g. bodies.rod.mass_scale=0.6".into(),
        )
    })?;
    let key = key.trim();
    let parsed = format!("v = {value}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"));
    // A number too large for a double (`1e400`) is not valid TOML; it is a number out of
    // range, not a string.
    if parsed.is_none() && value.trim().parse::<f64>().is_ok_and(|x| !x.is_finite()) {
        return Err(err(
            key,
            format!(
                "{} is not a finite number (the largest is about 1.8e308)",
                value.trim()
            ),
        ));
    }
    let value = parsed.unwrap_or_else(|| toml::Value::String(value.trim().to_string()));
    let parts: Vec<&str> = key.split('.').collect();
    let (last, parents) = parts
        .split_last()
        .ok_or_else(|| err(key, "empty key".into()))?;
    let mut cur = table;
    for (i, p) in parents.iter().enumerate() {
        let at = parts[..=i].join(".");
        let (name, index) = indexed(p).map_err(|m| err(key, m))?;
        let slot = match index {
            None => cur
                .entry(name.to_string())
                .or_insert_with(|| toml::Value::Table(toml::Table::new())),
            Some(k) => element(cur, name, k).map_err(|m| err(key, m))?,
        };
        cur = match slot {
            toml::Value::Table(t) => t,
            _ => return Err(err(key, format!("`{at}` is not a table"))),
        };
    }
    match indexed(last).map_err(|m| err(key, m))? {
        (name, None) => {
            cur.insert(name.to_string(), value);
        }
        (name, Some(k)) => *element(cur, name, k).map_err(|m| err(key, m))? = value,
    }
    Ok(key.to_string())
}

/// A `--set` key's part: its name and, for `name[k]`, the array index `k`.
fn indexed(part: &str) -> Result<(&str, Option<usize>), String> {
    let Some((name, rest)) = part.split_once('[') else {
        return Ok((part, None));
    };
    let index = rest
        .strip_suffix(']')
        .and_then(|k| k.trim().parse::<usize>().ok())
        .ok_or_else(|| {
            format!(
                "`{part}`: expected `{name}[INDEX]` with a whole number from 0, e.g. `{name}[0]`"
            )
        })?;
    Ok((name, Some(index)))
}

/// Element `k` of the array `name` in `table`: it must be there (a `--set` changes an element
/// of an array the rig has; it does not grow it).
fn element<'a>(
    table: &'a mut toml::Table,
    name: &str,
    k: usize,
) -> Result<&'a mut toml::Value, String> {
    match table.get_mut(name) {
        Some(toml::Value::Array(a)) => {
            let len = a.len();
            a.get_mut(k).ok_or_else(|| {
                format!(
                    "`{name}` has {len} entries (indices 0 to {}), not an entry {k}",
                    len.saturating_sub(1)
                )
            })
        }
        Some(_) => Err(format!("`{name}` is not an array: it takes no index")),
        None => Err(format!("no `{name}` here to index")),
    }
}

/// Overlay `child` on `base`: tables merge key by key, anything else replaces.
fn merge(base: &mut toml::Table, child: toml::Table) {
    for (k, v) in child {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(c)) => merge(b, c),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

/// The oil's descriptive keys: they describe one viscosity curve, so they do not survive a
/// change of `oil.viscosity` that does not restate them.
const OIL_DESCRIPTION: [&str; 3] = ["name", "grade", "source"];

/// Remove the oil's name, grade and source from a rig table (its viscosity is being replaced).
fn forget_oil_description(table: &mut toml::Table) {
    if let Some(toml::Value::Table(oil)) = table.get_mut("oil") {
        for k in OIL_DESCRIPTION {
            oil.remove(k);
        }
    }
}

/// Find the text of a rig named by `extends` in `from`: next to it on disk, else bundled.
/// `Ok(None)` if neither exists; a file that exists but cannot be read (a directory, a device,
/// too large) is an error, not a reason to look among the bundled rigs.
fn resolve_extends(from: &Path, name: &str) -> Result<Option<Source>, (PathBuf, ReadError)> {
    if let Some(dir) = from.parent() {
        let path = dir.join(name);
        match read_text(&path) {
            Ok(text) => return Ok(Some(Source { path, text })),
            Err(e) if e.is_not_found() => {}
            Err(e) => return Err((path, e)),
        }
    }
    Ok(crate::bundled::rig(name).map(|text| Source {
        path: PathBuf::from(format!("<bundled>/{name}")),
        text: text.to_string(),
    }))
}

/// Load a rig from `text` (named `path` in messages), resolve `extends`, apply `--set`
/// overrides, and validate.
pub fn load_rig_text(path: &Path, text: &str, sets: &[String]) -> Result<Rig, RigError> {
    let (sources, tables) = read_extends_chain(path, text)?;
    let single = tables.len() == 1;
    let mut table = merge_chain(tables);
    let overridden = apply_sets(&mut table, sets)?;
    let file = if single && sets.is_empty() {
        // The file exactly as written: toml's spans give precise locations.
        serde_path_to_error::deserialize::<_, RigFile>(toml::Deserializer::new(text)).map_err(
            |e| {
                let field = e.path().to_string();
                let err = serde_error(path, text, e.inner(), &field);
                unknown_key_in_table(err, &field, &table)
            },
        )?
    } else {
        // Merged tables have no spans: the path serde was at names the field, which is then
        // found in the file that sets it (or in --set); an unknown key is found by name.
        serde_path_to_error::deserialize::<_, RigFile>(toml::Value::Table(table.clone())).map_err(
            |e| {
                let field = e.path().to_string();
                let message = e.inner().message();
                if message.starts_with("unknown field") || field.is_empty() || field == "." {
                    let err = locate_key(&sources, message, &overridden);
                    unknown_key_in_table(err, &field, &table)
                } else {
                    field_error(&sources, &overridden, &field, message.to_string())
                }
            },
        )?
    };
    let mut rig = Rig {
        file,
        sources,
        overridden,
        law_origins: BTreeMap::new(),
        unattached: Vec::new(),
    };
    read_trace_file(&mut rig)?;
    validate(&rig)?;
    Ok(rig)
}

/// The rig's text and every file it `extends` (child first, at most 8 levels), each parsed
/// into a table with its `extends` key removed.
fn read_extends_chain(
    path: &Path,
    text: &str,
) -> Result<(Vec<Source>, Vec<toml::Table>), RigError> {
    let mut sources = vec![Source {
        path: path.to_path_buf(),
        text: text.to_string(),
    }];
    let parse = |src: &Source| -> Result<toml::Table, RigError> {
        toml::from_str(&src.text).map_err(|e| serde_error(&src.path, &src.text, &e, ""))
    };
    let mut tables = vec![parse(&sources[0])?];
    while let Some(ext) = tables.last_mut().and_then(|t| t.remove("extends")) {
        let from = sources.last().map(|s| s.path.clone()).unwrap_or_default();
        let name = ext.as_str().ok_or_else(|| {
            field_error(
                &sources,
                &[],
                "extends",
                "must be the file name of the rig to extend".into(),
            )
        })?;
        if sources.len() > 8 {
            return Err(field_error(
                &sources,
                &[],
                "extends",
                "more than 8 levels of `extends`: is there a cycle?".into(),
            ));
        }
        let base = resolve_extends(&from, name)
            .map_err(|(path, e)| {
                field_error(
                    &sources,
                    &[],
                    "extends",
                    format!("the rig to extend, `{}`, {e}", path.display()),
                )
            })?
            .ok_or_else(|| {
                field_error(
                    &sources,
                    &[],
                    "extends",
                    format!(
                        "cannot find `{name}` next to `{}` or among the bundled rigs",
                        from.display()
                    ),
                )
            })?;
        tables.push(parse(&base)?);
        sources.push(base);
    }
    Ok((sources, tables))
}

/// The tables of an `extends` chain (child first) merged, the base first and each child over
/// it. A child that replaces the oil's viscosity without naming the oil drops the base's name,
/// grade and source.
fn merge_chain(mut tables: Vec<toml::Table>) -> toml::Table {
    let mut table = tables.pop().unwrap_or_default();
    while let Some(child) = tables.pop() {
        let oil = child.get("oil").and_then(toml::Value::as_table);
        let names_oil = oil.is_some_and(|o| OIL_DESCRIPTION.iter().any(|k| o.contains_key(*k)));
        if oil.is_some_and(|o| o.contains_key("viscosity")) && !names_oil {
            forget_oil_description(&mut table);
        }
        merge(&mut table, child);
    }
    table
}

/// Apply `--set KEY=VALUE` overrides in order and return the dotted paths they changed. Sets
/// that replace the viscosity without naming the oil drop its name, grade and source first.
fn apply_sets(table: &mut toml::Table, sets: &[String]) -> Result<Vec<String>, RigError> {
    let set_keys: Vec<&str> = sets
        .iter()
        .map(|s| s.split_once('=').map_or(s.as_str(), |(k, _)| k).trim())
        .collect();
    let changes_viscosity = set_keys
        .iter()
        .any(|k| *k == "oil" || *k == "oil.viscosity" || k.starts_with("oil.viscosity."));
    let names_oil = set_keys
        .iter()
        .any(|k| OIL_DESCRIPTION.iter().any(|d| *k == format!("oil.{d}")));
    if changes_viscosity && !names_oil {
        forget_oil_description(table);
    }
    sets.iter().map(|s| apply_set(table, s)).collect()
}

/// Load a rig from disk, or a bundled rig by name (`crf250r-motored` or `crf250r-motored.toml`)
/// when no such file exists. `sets` are `--set KEY=VALUE` overrides; the result is validated,
/// and an error names the file (or `--set`), line, column and field.
///
/// ```
/// use std::path::Path;
/// use tribo_config::rig::load_rig;
///
/// // The bundled CRF 250 R rig, with the rod made 40% lighter.
/// let rig = load_rig(Path::new("crf250r-motored"), &["bodies.rod.mass_scale=0.6".into()])?;
/// assert_eq!(rig.file.bodies.rod.mass_scale, 0.6);
/// assert_eq!(rig.overridden, ["bodies.rod.mass_scale"]);
///
/// // A value out of range is refused, naming where it came from and the field.
/// let err = load_rig(Path::new("crf250r-motored"), &["geometry.bore_m=-1".into()])
///     .expect_err("a negative bore");
/// assert_eq!(
///     err.to_string(),
///     "--set: geometry.bore_m: must be a positive number (m), got -1"
/// );
/// # Ok::<(), tribo_config::rig::RigError>(())
/// ```
pub fn load_rig(path: &Path, sets: &[String]) -> Result<Rig, RigError> {
    match read_text(path) {
        Ok(text) => load_rig_text(path, &text, sets),
        Err(e) if !e.is_not_found() => Err(file_error(path, "rig file", &e)),
        Err(e) => {
            let name = path.to_string_lossy();
            match crate::bundled::rig(&name) {
                Some(text) => {
                    let file = crate::bundled::file_name(&name);
                    let file = if file.ends_with(".toml") {
                        file
                    } else {
                        format!("{file}.toml")
                    };
                    load_rig_text(&PathBuf::from(format!("<bundled>/{file}")), text, sets)
                }
                None => Err(RigError {
                    file: path.to_path_buf(),
                    line: None,
                    column: None,
                    field: "(file)".into(),
                    message: format!(
                        "{e}, and no bundled rig has that name; bundled: {}",
                        crate::bundled::rig_names()
                            .iter()
                            .map(|n| n.trim_end_matches(".toml"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                }),
            }
        }
    }
}

/// An unknown key named under the table it was found in (`drive.kp`, not `kp`; `table_path`
/// is the path serde was at), and for a table whose `kind` takes no settings (the prescribed
/// drive) that said plainly instead of serde's "there are no fields".
fn unknown_key_in_table(mut err: RigError, table_path: &str, table: &toml::Table) -> RigError {
    let Some(key) = err
        .message
        .strip_prefix("unknown field `")
        .and_then(|rest| rest.split('`').next())
        .map(str::to_string)
    else {
        return err;
    };
    if table_path.is_empty() || table_path == "." || err.field != key {
        return err;
    }
    err.field = if table_path.rsplit('.').next() == Some(key.as_str()) {
        table_path.to_string()
    } else {
        format!("{table_path}.{key}")
    };
    if err.message.ends_with("there are no fields") {
        let owner = err.field.rsplit_once('.').map_or("", |(t, _)| t);
        let kind = owner
            .split('.')
            .try_fold(table, |t, part| t.get(part)?.as_table())
            .and_then(|t| t.get("kind"))
            .and_then(|k| k.as_str());
        err.message = match kind {
            Some(kind) => format!(
                "unknown field `{key}`: `{owner}` of kind \"{kind}\" takes no settings besides `kind`"
            ),
            None => format!("unknown field `{key}`: `{owner}` takes no settings"),
        };
    }
    err
}

#[cfg(test)]
mod tests {
    use super::apply_set;

    fn table() -> toml::Table {
        "[drivetrain]\nelements = [{ kind = \"shaft\", k = 1.0 }, { kind = \"belt\", k = 2.0 }]\n"
            .parse()
            .unwrap()
    }

    #[test]
    fn a_set_reaches_an_array_element_and_refuses_one_the_array_has_not() {
        let mut t = table();
        apply_set(&mut t, "drivetrain.elements[1].k=5.0").unwrap();
        let elements = t["drivetrain"]["elements"].as_array().unwrap();
        assert_eq!(elements[1]["k"].as_float(), Some(5.0));
        assert_eq!(elements[0]["k"].as_float(), Some(1.0));
        apply_set(
            &mut t,
            "drivetrain.elements[0]={ kind = \"shaft\", k = 3.0 }",
        )
        .unwrap();
        assert_eq!(t["drivetrain"]["elements"][0]["k"].as_float(), Some(3.0));
        let out = apply_set(&mut t, "drivetrain.elements[2].k=1").unwrap_err();
        assert!(
            out.message.contains("2 entries") && out.message.contains("entry 2"),
            "{}",
            out.message
        );
        let bad = apply_set(&mut t, "drivetrain.elements[x].k=1").unwrap_err();
        assert!(bad.message.contains("whole number"), "{}", bad.message);
        let scalar = apply_set(&mut t, "drivetrain[0].k=1").unwrap_err();
        assert!(
            scalar.message.contains("not an array"),
            "{}",
            scalar.message
        );
    }
}
