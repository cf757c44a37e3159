//! Finding law libraries: explicit paths, then `TRIBO_PLUGIN_PATH`, then the directory of the
//! running executable. In a directory, only files named like a plugin
//! (`libtribo_law_*.so`, `tribo_law_*.dll`, ...) are considered, so a build directory full of
//! other libraries can be on the path; a file given explicitly is always loaded.

use std::collections::HashSet;
use std::env::consts::{DLL_PREFIX, DLL_SUFFIX};
use std::path::{Path, PathBuf};

use super::{LawError, LawLibrary};

/// Environment variable holding extra plugin directories (the platform's path-list syntax).
pub const PLUGIN_PATH_ENV: &str = "TRIBO_PLUGIN_PATH";

/// The file name a plugin library with crate lib-name `lib_name` gets on this platform.
pub fn plugin_file_name(lib_name: &str) -> String {
    format!("{DLL_PREFIX}{lib_name}{DLL_SUFFIX}")
}

fn looks_like_plugin(path: &Path) -> bool {
    let prefix = format!("{DLL_PREFIX}tribo_law_");
    path.file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.starts_with(&prefix) && n.ends_with(DLL_SUFFIX))
}

/// The set of loaded laws, at most one library per law name, ordered by name.
#[derive(Debug, Default)]
pub struct LawRegistry {
    libraries: Vec<LawLibrary>,
}

impl LawRegistry {
    /// An empty registry.
    pub fn new() -> Self {
        Self::default()
    }

    /// Add a library; a second library with the same law name is an error naming both files.
    pub fn insert(&mut self, lib: LawLibrary) -> Result<(), LawError> {
        if let Some(existing) = self.libraries.iter().find(|l| l.name() == lib.name()) {
            return Err(LawError::DuplicateName {
                name: lib.name().to_string(),
                first: existing.path().to_path_buf(),
                second: lib.path().to_path_buf(),
            });
        }
        let at = self.libraries.partition_point(|l| l.name() < lib.name());
        self.libraries.insert(at, lib);
        Ok(())
    }

    /// All libraries, ordered by law name.
    pub fn libraries(&self) -> &[LawLibrary] {
        &self.libraries
    }

    /// The library providing `name`.
    pub fn get(&self, name: &str) -> Result<&LawLibrary, LawError> {
        self.libraries
            .iter()
            .find(|l| l.name() == name)
            .ok_or_else(|| LawError::UnknownLaw {
                name: name.to_string(),
                available: if self.libraries.is_empty() {
                    "none (no plugin libraries were found)".into()
                } else {
                    self.libraries
                        .iter()
                        .map(|l| l.name())
                        .collect::<Vec<_>>()
                        .join(", ")
                },
            })
    }
}

/// Load every law reachable from `explicit` (files or directories), the directories in
/// `TRIBO_PLUGIN_PATH`, and the directory holding the running executable.
pub fn discover(explicit: &[PathBuf]) -> Result<LawRegistry, LawError> {
    let mut files = explicit_files(explicit)?;
    if let Some(list) = std::env::var_os(PLUGIN_PATH_ENV) {
        for dir in std::env::split_paths(&list) {
            if dir.is_dir() {
                scan_dir(&dir, &mut files)?;
            }
        }
    }
    if let Some(dir) = std::env::current_exe()
        .ok()
        .and_then(|p| p.parent().map(Path::to_path_buf))
    {
        scan_dir(&dir, &mut files)?;
    }
    load_files(files)
}

/// Load only what `paths` (files or directories) hold: no environment, no executable
/// directory. For tools and tests that must not depend on where they run.
pub fn load_paths(paths: &[PathBuf]) -> Result<LawRegistry, LawError> {
    load_files(explicit_files(paths)?)
}

fn explicit_files(paths: &[PathBuf]) -> Result<Vec<PathBuf>, LawError> {
    let mut files = Vec::new();
    for path in paths {
        if path.is_dir() {
            scan_dir(path, &mut files)?;
        } else {
            files.push(path.clone());
        }
    }
    Ok(files)
}

fn load_files(files: Vec<PathBuf>) -> Result<LawRegistry, LawError> {
    let mut seen = HashSet::new();
    let mut registry = LawRegistry::new();
    for file in files {
        // The same file reached twice (exe dir also on the plugin path) is loaded once.
        let key = std::fs::canonicalize(&file).unwrap_or_else(|_| file.clone());
        if seen.insert(key) {
            registry.insert(LawLibrary::load(&file)?)?;
        }
    }
    Ok(registry)
}

fn scan_dir(dir: &Path, out: &mut Vec<PathBuf>) -> Result<(), LawError> {
    let io = |source| LawError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut found = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        if path.is_file() && looks_like_plugin(&path) {
            found.push(path);
        }
    }
    found.sort();
    out.extend(found);
    Ok(())
}
