//! Where a rig problem is: the file (or `--set`), line, column and dotted field, found in the
//! text of the file that gives the value.

use std::path::{Path, PathBuf};

use super::Source;
use crate::files::ReadError;

/// A rig problem with where it is.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {field}: {message}", location(file, *line, *column))]
pub struct RigError {
    /// File (or `--set` for an override).
    pub file: PathBuf,
    /// 1-based line, if known.
    pub line: Option<usize>,
    /// 1-based column, if known.
    pub column: Option<usize>,
    /// Dotted path of the field.
    pub field: String,
    /// What is wrong and what is allowed.
    pub message: String,
}

impl RigError {
    /// An error about `field` of the TOML `text` read from `path`, located at the field's line
    /// and column when it can be found there.
    pub fn at(path: &Path, text: &str, field: &str, message: String) -> Self {
        let at = locate(text, field).map(|s| line_col(text, s.start));
        Self {
            file: path.to_path_buf(),
            line: at.map(|a| a.0),
            column: at.map(|a| a.1),
            field: field.into(),
            message,
        }
    }
}

pub(super) fn location(file: &Path, line: Option<usize>, col: Option<usize>) -> String {
    match (line, col) {
        (Some(l), Some(c)) => format!("{}:{l}:{c}", file.display()),
        _ => file.display().to_string(),
    }
}

/// Line and column (1-based) of byte `offset` in `text`.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// Byte span of the value at dotted `path` (`joints.big_end.laws[0].law`) in a TOML text.
pub fn locate(text: &str, path: &str) -> Option<std::ops::Range<usize>> {
    let doc = toml_edit::ImDocument::parse(text).ok()?;
    let mut item: &toml_edit::Item = doc.as_item();
    let mut span = None;
    for part in path.split('.') {
        let (key, index) = match part.split_once('[') {
            Some((k, rest)) => (k, rest.trim_end_matches(']').parse::<usize>().ok()),
            None => (part, None),
        };
        item = item.get(key)?;
        span = item.span().or(span);
        if let Some(i) = index {
            item = item.get(i)?;
            span = item.span().or(span);
        }
    }
    span
}

pub(super) fn field_error(
    sources: &[Source],
    overridden: &[String],
    field: &str,
    message: String,
) -> RigError {
    if overridden
        .iter()
        .any(|o| field.starts_with(o.as_str()) || o.starts_with(field))
    {
        return RigError {
            file: PathBuf::from("--set"),
            line: None,
            column: None,
            field: field.into(),
            message,
        };
    }
    for src in sources {
        if let Some(span) = locate(&src.text, field) {
            let (l, c) = line_col(&src.text, span.start);
            return RigError {
                file: src.path.clone(),
                line: Some(l),
                column: Some(c),
                field: field.into(),
                message,
            };
        }
    }
    RigError {
        file: sources.first().map(|s| s.path.clone()).unwrap_or_default(),
        line: None,
        column: None,
        field: field.into(),
        message,
    }
}

/// A deserialisation error of one file read as written; `field` is the dotted path serde was
/// at (empty when unknown).
pub(super) fn serde_error(path: &Path, text: &str, e: &toml::de::Error, field: &str) -> RigError {
    let message = e.message().to_string();
    let (line, column, field) = match e.span() {
        Some(span) => {
            let (l, c) = line_col(text, span.start);
            // An unknown key is named by the message (`unknown field `x``); any other error
            // is at the path serde was deserialising; failing both, the key written on the
            // offending line, else the line itself is the best description.
            let unknown = message.starts_with("unknown field");
            let at_path =
                (!unknown && !field.is_empty() && field != ".").then(|| field.to_string());
            let named = message.split('`').nth(1).filter(|k| {
                unknown
                    && !k.is_empty()
                    && k.chars()
                        .all(|c| c.is_alphanumeric() || c == '_' || c == '-')
            });
            let line_key = text
                .lines()
                .nth(l - 1)
                .and_then(|t| t.split_once('='))
                .map(|(k, _)| k.trim().to_string())
                .filter(|k| !k.is_empty());
            let field = at_path
                .or(named.map(str::to_string))
                .or(line_key)
                .unwrap_or_else(|| "(syntax)".into());
            (Some(l), Some(c), field)
        }
        None => (None, None, "(file)".into()),
    };
    RigError {
        file: path.to_path_buf(),
        line,
        column,
        field,
        message,
    }
}

/// Where a key named in a serde message (`unknown field `x``) is written, for errors found
/// after merging, when toml's own spans are gone.
pub(super) fn locate_key(sources: &[Source], message: &str, overridden: &[String]) -> RigError {
    let key = message.split('`').nth(1).unwrap_or("");
    if !key.is_empty() {
        for src in sources {
            for (i, line) in src.text.lines().enumerate() {
                let t = line.trim_start();
                let hit = t
                    .strip_prefix('[')
                    .map(|h| {
                        h.trim_start_matches('[')
                            .split(['.', ']'])
                            .any(|p| p.trim() == key)
                    })
                    .unwrap_or_else(|| {
                        t.split('=')
                            .next()
                            .is_some_and(|k| k.trim() == key && t.contains('='))
                    });
                if hit {
                    return RigError {
                        file: src.path.clone(),
                        line: Some(i + 1),
                        column: Some(line.len() - t.len() + 1),
                        field: key.into(),
                        message: message.into(),
                    };
                }
            }
        }
    }
    RigError {
        file: if overridden.is_empty() {
            sources.first().map(|s| s.path.clone()).unwrap_or_default()
        } else {
            PathBuf::from("--set")
        },
        line: None,
        column: None,
        field: if key.is_empty() {
            overridden.join(", ")
        } else {
            key.into()
        },
        message: message.into(),
    }
}

/// An error about the file at `path` as a whole: the `what` (e.g. `rig file`) cannot be read.
pub fn file_error(path: &Path, what: &str, e: &ReadError) -> RigError {
    RigError {
        file: path.to_path_buf(),
        line: None,
        column: None,
        field: "(file)".into(),
        message: format!("the {what} {e}"),
    }
}
