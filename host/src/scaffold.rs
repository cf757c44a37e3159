//! `tribo new-law`: generate a law plugin crate from the templates in `host/templates/law`.

use std::path::{Component, Path, PathBuf};

/// Why a scaffold could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ScaffoldError {
    /// The name is not usable as a law and crate name.
    #[error("`{0}` is not a valid law name: use lowercase letters, digits and single hyphens, starting with a letter (e.g. `my-law`)")]
    BadName(String),
    /// No Tribo checkout above the starting directory.
    #[error("no Tribo workspace (a Cargo.toml beside plugin-api/) found in `{0}` or above; run `tribo new-law` inside a Tribo checkout")]
    NoWorkspace(PathBuf),
    /// Refuse to overwrite.
    #[error("`{0}` already exists; choose another name or --dir")]
    Exists(PathBuf),
    /// File system error.
    #[error("cannot write `{path}`: {source}")]
    Io {
        /// Path.
        path: PathBuf,
        /// OS error.
        source: std::io::Error,
    },
}

/// What was generated.
#[derive(Debug)]
pub struct Scaffold {
    /// Crate directory.
    pub dir: PathBuf,
    /// Cargo package name.
    pub crate_name: String,
    /// File name of the built library.
    pub library_file: String,
    /// Whether the crate is a member of the Tribo workspace.
    pub workspace_member: bool,
}

fn valid_name(name: &str) -> bool {
    let mut chars = name.chars();
    chars.next().is_some_and(|c| c.is_ascii_lowercase())
        && name.len() <= 48
        && name
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
        && !name.ends_with('-')
        && !name.contains("--")
}

/// The Tribo workspace root at or above `start`.
pub fn find_workspace(start: &Path) -> Option<PathBuf> {
    start.ancestors().find_map(|dir| {
        let is_root = dir.join("plugin-api/Cargo.toml").is_file()
            && std::fs::read_to_string(dir.join("Cargo.toml"))
                .is_ok_and(|t| t.contains("[workspace]"));
        is_root.then(|| dir.to_path_buf())
    })
}

/// `to` relative to `from` (both absolute, normalised), with `/` separators for Cargo.toml.
fn relative(from: &Path, to: &Path) -> String {
    let f: Vec<Component> = from.components().collect();
    let t: Vec<Component> = to.components().collect();
    let common = f.iter().zip(&t).take_while(|(a, b)| a == b).count();
    let mut parts: Vec<String> = vec!["..".into(); f.len() - common];
    parts.extend(
        t[common..]
            .iter()
            .map(|c| c.as_os_str().to_string_lossy().into_owned()),
    );
    parts.join("/")
}

fn absolute(p: &Path) -> std::io::Result<PathBuf> {
    let abs = std::path::absolute(p)?;
    // Normalise `..` so relative paths come out short and right.
    let mut out = PathBuf::new();
    for c in abs.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    Ok(out)
}

/// Generate crate `name` in `dir` (default: `<workspace>/plugins`), starting the workspace search
/// at `cwd`.
pub fn new_law(name: &str, dir: Option<&Path>, cwd: &Path) -> Result<Scaffold, ScaffoldError> {
    if !valid_name(name) {
        return Err(ScaffoldError::BadName(name.into()));
    }
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| ScaffoldError::Io { path, source }
    };
    let cwd = absolute(cwd).map_err(io(cwd))?;
    let ws = find_workspace(&cwd).ok_or_else(|| ScaffoldError::NoWorkspace(cwd.clone()))?;
    let parent = match dir {
        Some(d) => absolute(&cwd.join(d)).map_err(io(d))?,
        None => ws.join("plugins"),
    };
    let crate_dir = parent.join(name);
    if crate_dir.exists() {
        return Err(ScaffoldError::Exists(crate_dir));
    }
    // The workspace takes every directory under plugins/ as a member; anywhere else the new
    // crate is its own workspace so Cargo does not complain about an unlisted member.
    let workspace_member = parent == ws.join("plugins");
    let snake = name.replace('-', "_");
    let lib = format!("tribo_law_{snake}");
    let type_name: String = name
        .split('-')
        .map(|w| {
            let mut c = w.chars();
            c.next()
                .map(|f| f.to_ascii_uppercase().to_string() + c.as_str())
                .unwrap_or_default()
        })
        .collect();
    let crate_name = format!("tribo-law-{name}");
    let library_file = tribo_plugin_api::loader::plugin_file_name(&lib);
    let fill =
        |t: &str| {
            t.replace("{{name}}", name)
            .replace("{{crate}}", &crate_name)
            .replace("{{lib}}", &lib)
            .replace("{{type}}", &type_name)
            .replace("{{file}}", &library_file)
            .replace("{{api_path}}", &relative(&crate_dir, &ws.join("plugin-api")))
            .replace(
                "{{workspace_table}}",
                if workspace_member {
                    ""
                } else {
                    "\n# Not a member of the Tribo workspace: this crate is its own.\n[workspace]\n"
                },
            )
        };
    let files = [
        (
            "Cargo.toml",
            include_str!("../templates/law/Cargo.toml.tmpl"),
        ),
        ("src/lib.rs", include_str!("../templates/law/lib.rs.tmpl")),
        ("README.md", include_str!("../templates/law/README.md.tmpl")),
    ];
    let src = crate_dir.join("src");
    std::fs::create_dir_all(&src).map_err(io(&src))?;
    for (rel, template) in files {
        let path = crate_dir.join(rel);
        std::fs::write(&path, fill(template)).map_err(io(&path))?;
    }
    Ok(Scaffold {
        dir: crate_dir,
        crate_name,
        library_file,
        workspace_member,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names() {
        assert!(valid_name("my-law"));
        assert!(valid_name("stribeck2"));
        for bad in ["", "My-law", "-x", "x-", "a--b", "a_b", "1law", "a b"] {
            assert!(!valid_name(bad), "{bad}");
        }
    }

    #[test]
    fn relative_paths() {
        assert_eq!(
            relative(Path::new("/w/plugins/x"), Path::new("/w/plugin-api")),
            "../../plugin-api"
        );
        assert_eq!(
            relative(Path::new("/tmp/a"), Path::new("/w/plugin-api")),
            "../../w/plugin-api"
        );
    }
}
