//! Finding law libraries: explicit paths, then `TRIBO_PLUGIN_PATH`, then the directory of the
//! running executable. In a directory, only files named like a plugin
//! (`libtribo_law_*.so`, `tribo_law_*.dll`, ...) are considered, so a build directory full of
//! other libraries can be on the path; a file given explicitly is always loaded.
//!
//! Opening a library runs its initialisers (native code with the user's rights), so discovery
//! only lists the files it finds. A file given explicitly is opened at once (the user asked for
//! it, and a failure is an error); a file found in a directory is opened when a law is asked for
//! ([`LawRegistry::get`]): first the files named for that law (law `stribeck-duty`, file
//! `libtribo_law_stribeck_duty.so`), and only if none of them provides it, the others in search
//! order. [`LawRegistry::open_all`] opens everything, for `tribo laws`.

use std::collections::HashSet;
use std::env::consts::{DLL_PREFIX, DLL_SUFFIX};
use std::fmt;
use std::fs::Metadata;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use super::{LawError, LawLibrary};

/// Environment variable holding extra plugin directories (the platform's path-list syntax).
pub const PLUGIN_PATH_ENV: &str = "TRIBO_PLUGIN_PATH";

/// The part of a plugin's file name before the law's name (`libtribo_law_` on Unix).
fn plugin_prefix() -> String {
    format!("{DLL_PREFIX}tribo_law_")
}

/// The file name a plugin library with crate lib-name `lib_name` gets on this platform.
pub fn plugin_file_name(lib_name: &str) -> String {
    format!("{DLL_PREFIX}{lib_name}{DLL_SUFFIX}")
}

/// The law name a plugin file promises by its name, with `_` where the law has `-`
/// (`libtribo_law_stribeck_duty.so` -> `stribeck_duty`); `None` for other files.
fn promised_name(path: &Path) -> Option<String> {
    let name = path.file_name()?.to_str()?;
    let stem = name
        .strip_prefix(&plugin_prefix())?
        .strip_suffix(DLL_SUFFIX)?;
    Some(stem.to_string())
}

/// Whether a file name's promise `stem` is law `name` (`-` in the law name is `_` in the file
/// name, as a cargo lib-name has it).
fn promises(stem: &str, name: &str) -> bool {
    stem.len() == name.len()
        && stem
            .bytes()
            .zip(name.bytes())
            .all(|(s, n)| s == if n == b'-' { b'_' } else { n })
}

/// A file found in a plugin directory, opened at most once, when first needed.
#[derive(Debug)]
struct Candidate {
    path: PathBuf,
    /// What the file name promises ([`promised_name`]).
    stem: String,
    opened: OnceLock<Result<LawLibrary, LawError>>,
}

/// How a [`LawRegistry`] opens a file: [`LawLibrary::load`], or a stand-in in unit tests.
type Opener = fn(&Path) -> Result<LawLibrary, LawError>;

impl Candidate {
    fn open(&self, opener: Opener) -> Result<&LawLibrary, &LawError> {
        self.opened.get_or_init(|| opener(&self.path)).as_ref()
    }
}

/// A plugin file or directory on the search path that someone other than its owner can write:
/// whoever can write there can put a library in it that runs code as the user.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WritableWarning {
    /// The directory or file.
    pub path: PathBuf,
    /// `true` for a directory, `false` for a plugin file.
    pub is_dir: bool,
    /// Its permission bits (`0o777` part of the mode).
    pub mode: u32,
    /// Who besides the owner can write it: `"anyone"` or `"its group"`.
    pub writers: &'static str,
}

impl fmt::Display for WritableWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let what = if self.is_dir {
            "plugin directory"
        } else {
            "plugin file"
        };
        write!(
            f,
            "{what} `{}` can be written by {} (mode {:04o}): whoever can write there can make tribo run their code as you; keep law plugins where only you can write (chmod go-w)",
            self.path.display(),
            self.writers,
            self.mode
        )
    }
}

/// Who besides the owner may write a file of permission bits `mode`, owned by user `uid` and
/// group `gid`. A group-writable file whose group id equals its owner's user id is taken for
/// a user-private group (the Debian, Ubuntu and Fedora convention, where a umask of 002 makes
/// every new directory group-writable and the group holds only its user) and not reported.
fn other_writers(mode: u32, uid: u32, gid: u32) -> Option<&'static str> {
    if mode & 0o002 != 0 {
        Some("anyone")
    } else if mode & 0o020 != 0 && gid != uid {
        Some("its group")
    } else {
        None
    }
}

#[cfg(unix)]
fn writable_warning(path: &Path, meta: &Metadata) -> Option<WritableWarning> {
    use std::os::unix::fs::MetadataExt;
    let mode = meta.mode() & 0o7777;
    other_writers(mode, meta.uid(), meta.gid()).map(|writers| WritableWarning {
        path: path.to_path_buf(),
        is_dir: meta.is_dir(),
        mode,
        writers,
    })
}

#[cfg(not(unix))]
fn writable_warning(_path: &Path, _meta: &Metadata) -> Option<WritableWarning> {
    // Windows ACLs are not inspected: the warning is a Unix mode check.
    None
}

/// Every law reachable from the search path. Libraries given explicitly (or inserted) are open;
/// files found in directories are opened on demand and kept open, so the registry can be shared
/// by the threads of a study (it is `Sync`). At most one library may provide a law name.
#[derive(Debug)]
pub struct LawRegistry {
    /// Opened up front: explicit `--plugin` files and inserted libraries, in the order given.
    loaded: Vec<LawLibrary>,
    /// Files found in plugin directories, in search order, each opened when first needed.
    candidates: Vec<Candidate>,
    /// Directories and files on the search path that others can write.
    warnings: Vec<WritableWarning>,
    opener: Opener,
}

impl Default for LawRegistry {
    fn default() -> Self {
        Self {
            loaded: Vec::new(),
            candidates: Vec::new(),
            warnings: Vec::new(),
            opener: LawLibrary::load,
        }
    }
}

/// Every law of a registry, all candidates opened: what `tribo laws` shows.
#[derive(Debug)]
pub struct LawListing<'a> {
    /// The libraries that opened, ordered by law name.
    pub laws: Vec<&'a LawLibrary>,
    /// Files that were found in a plugin directory but could not be opened as a law, in search
    /// order, with the reason.
    pub broken: Vec<(&'a Path, &'a LawError)>,
}

impl LawRegistry {
    /// An empty registry.
    pub fn new() -> Self {
        Self::default()
    }

    /// Add an open library; a second library with the same law name (among those open) is an
    /// error naming both files.
    pub fn insert(&mut self, lib: LawLibrary) -> Result<(), LawError> {
        let opened = self
            .candidates
            .iter()
            .filter_map(|c| c.opened.get().and_then(|r| r.as_ref().ok()));
        if let Some(existing) = self
            .loaded
            .iter()
            .chain(opened)
            .find(|l| l.name() == lib.name())
        {
            return Err(LawError::DuplicateName {
                name: lib.name().to_string(),
                first: existing.path().to_path_buf(),
                second: lib.path().to_path_buf(),
            });
        }
        self.loaded.push(lib);
        Ok(())
    }

    /// Plugin directories and files on the search path that others than their owner can write,
    /// once each, found when the registry was discovered.
    pub fn warnings(&self) -> &[WritableWarning] {
        &self.warnings
    }

    /// The library providing `name`. Looked for among the open libraries and the files named for
    /// the law (all of them are opened: two providers are [`LawError::DuplicateName`]); if none
    /// provides it, the other files are opened in search order until one does. Files that
    /// cannot be opened are skipped, and named in the [`LawError::UnknownLaw`] error when the
    /// law is not found. The answer does not depend on what was opened before.
    pub fn get(&self, name: &str) -> Result<&LawLibrary, LawError> {
        let named = self.candidates.iter().filter(|c| promises(&c.stem, name));
        let mut found: Option<&LawLibrary> = None;
        for lib in self
            .loaded
            .iter()
            .chain(named.filter_map(|c| c.open(self.opener).ok()))
            .filter(|l| l.name() == name)
        {
            if let Some(first) = found {
                return Err(LawError::DuplicateName {
                    name: name.to_string(),
                    first: first.path().to_path_buf(),
                    second: lib.path().to_path_buf(),
                });
            }
            found = Some(lib);
        }
        if let Some(lib) = found {
            return Ok(lib);
        }
        // A library whose file name is not its law's: still found, only opened later.
        for c in self.candidates.iter().filter(|c| !promises(&c.stem, name)) {
            if let Ok(lib) = c.open(self.opener) {
                if lib.name() == name {
                    return Ok(lib);
                }
            }
        }
        // Every candidate is open now: name what exists and what could not be opened.
        let listing = self.opened();
        let mut available: Vec<&str> = listing.laws.iter().map(|l| l.name()).collect();
        available.dedup();
        Err(LawError::UnknownLaw {
            name: name.to_string(),
            available: if available.is_empty() && listing.broken.is_empty() {
                "none (no plugin libraries were found)".into()
            } else if available.is_empty() {
                "none".into()
            } else {
                available.join(", ")
            },
            broken: listing.broken.iter().map(|(_, e)| e.to_string()).collect(),
        })
    }

    /// Never open the file `path` found in a plugin directory: it counts as a file that could
    /// not be opened, for `reason` (loading it ended or hung a worker process, say). A file
    /// already opened, or not found, is left as it is.
    pub fn skip(&self, path: &Path, reason: String) {
        for c in self.candidates.iter().filter(|c| c.path == path) {
            let _ = c.opened.set(Err(LawError::Skipped {
                path: path.to_path_buf(),
                reason: reason.clone(),
            }));
        }
    }

    /// Open every library found (running each one's initialisers) and list them: the laws by
    /// name and the files that could not be opened. Two libraries providing one law name are
    /// [`LawError::DuplicateName`], naming both files.
    pub fn open_all(&self) -> Result<LawListing<'_>, LawError> {
        for c in &self.candidates {
            let _ = c.open(self.opener);
        }
        let listing = self.opened();
        if let Some(pair) = listing.laws.windows(2).find(|w| w[0].name() == w[1].name()) {
            return Err(LawError::DuplicateName {
                name: pair[0].name().to_string(),
                first: pair[0].path().to_path_buf(),
                second: pair[1].path().to_path_buf(),
            });
        }
        Ok(listing)
    }

    /// What is open so far: laws ordered by name (ties in search order), and the failures.
    fn opened(&self) -> LawListing<'_> {
        let mut laws: Vec<&LawLibrary> = self.loaded.iter().collect();
        let mut broken = Vec::new();
        for c in &self.candidates {
            match c.opened.get() {
                Some(Ok(lib)) => laws.push(lib),
                Some(Err(e)) => broken.push((c.path.as_path(), e)),
                None => {}
            }
        }
        // Stable: a duplicate pair stays in search order.
        laws.sort_by(|a, b| a.name().cmp(b.name()));
        LawListing { laws, broken }
    }
}

/// Find every law reachable from `explicit` (files or directories), the directories in
/// `TRIBO_PLUGIN_PATH`, and the directory holding the running executable. Explicit files are
/// opened now (a failure is an error); files in directories are only listed, and opened when a
/// law is asked for ([`LawRegistry::get`]).
pub fn discover(explicit: &[PathBuf]) -> Result<LawRegistry, LawError> {
    let mut search = Search::default();
    search.explicit(explicit)?;
    if let Some(list) = std::env::var_os(PLUGIN_PATH_ENV) {
        for dir in std::env::split_paths(&list) {
            if dir.is_dir() {
                search.scan_dir(&dir)?;
            }
        }
    }
    if let Some(dir) = std::env::current_exe()
        .ok()
        .and_then(|p| p.parent().map(Path::to_path_buf))
    {
        search.scan_dir(&dir)?;
    }
    Ok(search.registry)
}

/// Find only what `paths` (files or directories) hold: no environment, no executable
/// directory. For tools and tests that must not depend on where they run. Explicit files are
/// opened now, directory files when asked for, as in [`discover`].
pub fn load_paths(paths: &[PathBuf]) -> Result<LawRegistry, LawError> {
    let mut search = Search::default();
    search.explicit(paths)?;
    Ok(search.registry)
}

/// A registry being assembled from the search path.
#[derive(Default)]
struct Search {
    registry: LawRegistry,
    /// Canonical paths of the files taken so far: the same file reached twice (the executable's
    /// directory also on the plugin path) is taken once.
    seen_files: HashSet<PathBuf>,
    /// Canonical paths of the directories checked for writers, so each is reported once.
    checked_dirs: HashSet<PathBuf>,
}

fn canonical(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
}

impl Search {
    fn explicit(&mut self, paths: &[PathBuf]) -> Result<(), LawError> {
        for path in paths {
            if path.is_dir() {
                self.scan_dir(path)?;
            } else {
                if let Some(dir) = path.parent() {
                    // `lib.so` has the parent "": the working directory.
                    let dir = if dir.as_os_str().is_empty() {
                        Path::new(".")
                    } else {
                        dir
                    };
                    self.check_dir(dir);
                }
                self.check_file(path);
                if self.seen_files.insert(canonical(path)) {
                    self.registry.insert(LawLibrary::load(path)?)?;
                }
            }
        }
        Ok(())
    }

    fn check_dir(&mut self, dir: &Path) {
        if !self.checked_dirs.insert(canonical(dir)) {
            return;
        }
        if let Ok(meta) = std::fs::metadata(dir) {
            self.registry.warnings.extend(writable_warning(dir, &meta));
        }
    }

    fn check_file(&mut self, file: &Path) {
        if let Ok(meta) = std::fs::metadata(file) {
            self.registry.warnings.extend(writable_warning(file, &meta));
        }
    }

    fn scan_dir(&mut self, dir: &Path) -> Result<(), LawError> {
        let io = |error| LawError::Io {
            path: dir.to_path_buf(),
            error,
        };
        self.check_dir(dir);
        let mut found = Vec::new();
        for entry in std::fs::read_dir(dir).map_err(io)? {
            let path = entry.map_err(io)?.path();
            if path.is_file() {
                if let Some(stem) = promised_name(&path) {
                    found.push((path, stem));
                }
            }
        }
        found.sort();
        for (path, stem) in found {
            if self.seen_files.insert(canonical(&path)) {
                self.check_file(&path);
                self.registry.candidates.push(Candidate {
                    path,
                    stem,
                    opened: OnceLock::new(),
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contract::{LawInput, LawOutput};
    use crate::describe::{ParamError, ParamSpec};
    use crate::law::Law;
    use std::sync::Mutex;

    #[derive(Debug, Default, serde::Serialize, serde::Deserialize)]
    struct NoParams {}

    /// A law without parameters; the stand-in opener renames it per file.
    struct Stub;

    impl Law for Stub {
        type Params = NoParams;
        const NAME: &'static str = "stub";
        const VERSION: &'static str = "0.0.0";
        const SUMMARY: &'static str = "registry test law";
        fn parameters() -> Vec<ParamSpec> {
            Vec::new()
        }
        fn new(_: NoParams) -> Result<Self, ParamError> {
            Ok(Self)
        }
        fn evaluate(&self, _: &LawInput, _: &[f64]) -> LawOutput {
            LawOutput::force(0.0)
        }
    }

    /// Every path the stand-in opener was asked to open, from every test.
    static OPENED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

    /// A stand-in for `LawLibrary::load` that records the open. A file whose name holds
    /// `broken` fails to open; a file in a directory `provides-LAW` provides law `LAW`; any
    /// other provides the law its file name promises.
    fn fake_open(path: &Path) -> Result<LawLibrary, LawError> {
        OPENED.lock().expect("lock").push(path.to_path_buf());
        let stem = promised_name(path).expect("test paths are plugin names");
        if stem.contains("broken") {
            return Err(LawError::NotALibrary {
                path: path.to_path_buf(),
                reason: "invalid ELF header".into(),
            });
        }
        let dir = path
            .parent()
            .and_then(|d| d.file_name())
            .and_then(|d| d.to_str());
        let law = match dir.and_then(|d| d.strip_prefix("provides-")) {
            Some(law) => law.to_string(),
            None => stem.replace('_', "-"),
        };
        let mut lib = LawLibrary::in_process::<Stub>().expect("describes itself");
        lib.description.name = law;
        lib.path = path.to_path_buf();
        Ok(lib)
    }

    /// A candidate for file `name` (`tribo_law_` and the suffix added) in `dir`.
    fn candidate(dir: &str, name: &str) -> Candidate {
        let path = Path::new(dir).join(plugin_file_name(&format!("tribo_law_{name}")));
        Candidate {
            stem: promised_name(&path).expect("plugin name"),
            path,
            opened: OnceLock::new(),
        }
    }

    /// A registry of candidate files `names` in directory `dir` (nothing on disk), opened by
    /// [`fake_open`].
    fn registry(dir: &str, names: &[&str]) -> LawRegistry {
        LawRegistry {
            opener: fake_open,
            candidates: names.iter().map(|n| candidate(dir, n)).collect(),
            ..LawRegistry::default()
        }
    }

    /// File names (without prefix and suffix) opened under `dir`, in order.
    fn opened_in(dir: &str) -> Vec<String> {
        OPENED
            .lock()
            .expect("lock")
            .iter()
            .filter(|p| p.starts_with(dir))
            .map(|p| promised_name(p).expect("plugin name"))
            .collect()
    }

    #[test]
    fn file_names_promise_laws_with_underscores_for_dashes() {
        let p = Path::new("/x").join(plugin_file_name("tribo_law_stribeck_duty"));
        assert_eq!(promised_name(&p).as_deref(), Some("stribeck_duty"));
        assert!(promises("stribeck_duty", "stribeck-duty"));
        assert!(promises("coulomb", "coulomb"));
        assert!(!promises("coulomb", "c-coulomb"));
        assert!(!promises("c_coulomb", "coulomb"));
        assert!(!promises("stribeck_duty", "stribeck-dut"));
        let other = Path::new("/x").join(plugin_file_name("tribo_fixture_panic_law"));
        assert_eq!(promised_name(&other), None);
        assert_eq!(promised_name(Path::new("/x/libtribo_law_a.so.txt")), None);
    }

    #[test]
    fn get_opens_only_the_file_named_for_the_law() {
        let dir = "/t-named";
        let reg = registry(dir, &["alpha", "broken", "gamma_ray", "zeta"]);
        let lib = reg.get("gamma-ray").expect("found by name");
        assert_eq!(lib.name(), "gamma-ray");
        assert_eq!(opened_in(dir), ["gamma_ray"]);
        // Cached: asking again opens nothing more; another law opens only its own file.
        assert!(std::ptr::eq(reg.get("gamma-ray").expect("again"), lib));
        reg.get("alpha").expect("alpha");
        assert_eq!(opened_in(dir), ["gamma_ray", "alpha"]);
        // The broken file was never opened, so it cannot have failed anything.
        assert!(reg.candidates[1].opened.get().is_none());
    }

    #[test]
    fn a_library_not_named_for_its_law_is_found_by_scanning_the_others() {
        let dir = "/t-scan";
        let mut reg = registry(dir, &["alpha", "broken"]);
        reg.candidates
            .push(candidate("/t-scan/provides-beta", "misnamed"));
        reg.candidates.push(candidate(dir, "zeta"));
        let lib = reg.get("beta").expect("found by scanning");
        assert_eq!(lib.name(), "beta");
        // In search order until found: the later `zeta` stays closed.
        assert_eq!(opened_in(dir), ["alpha", "broken", "misnamed"]);
        assert!(reg.candidates[3].opened.get().is_none());
    }

    #[test]
    fn a_file_named_for_another_law_does_not_shadow_the_real_provider() {
        // `libtribo_law_beta` holds law `other`; the law `beta` is in a mis-named file.
        let mut reg = registry("/t-shadow", &[]);
        reg.candidates
            .push(candidate("/t-shadow/provides-other", "beta"));
        reg.candidates
            .push(candidate("/t-shadow/provides-beta", "x"));
        assert_eq!(
            reg.get("beta").expect("found").path(),
            reg.candidates[1].path
        );
        assert_eq!(
            reg.get("other").expect("found").path(),
            reg.candidates[0].path
        );
    }

    #[test]
    fn two_files_named_for_one_law_are_a_duplicate_naming_both() {
        let mut reg = registry("/t-dup-a", &["alpha"]);
        reg.candidates
            .extend(registry("/t-dup-b", &["alpha", "zeta"]).candidates);
        let e = reg.get("alpha").unwrap_err();
        let msg = e.to_string();
        assert!(
            matches!(&e, LawError::DuplicateName { name, first, second }
                if name == "alpha" && first.starts_with("/t-dup-a") && second.starts_with("/t-dup-b")),
            "{msg}"
        );
        // Both were opened to see it, the unrelated `zeta` was not.
        assert!(reg.candidates[2].opened.get().is_none());
    }

    #[test]
    fn an_inserted_library_and_a_file_named_for_its_law_are_a_duplicate() {
        let mut reg = registry("/t-dup-ins", &["stub"]);
        reg.insert(LawLibrary::in_process::<Stub>().expect("describes itself"))
            .expect("nothing open yet");
        let e = reg.get("stub").unwrap_err();
        assert!(matches!(e, LawError::DuplicateName { .. }), "{e}");
        // Inserting a second `stub` once one is open is refused at once.
        let e = reg
            .insert(LawLibrary::in_process::<Stub>().expect("describes itself"))
            .unwrap_err();
        assert!(matches!(e, LawError::DuplicateName { .. }), "{e}");
    }

    #[test]
    fn duplicates_by_scan_are_seen_by_open_all() {
        let mut reg = registry("/t-dup-scan", &["alpha"]);
        reg.candidates
            .push(candidate("/t-dup-scan/provides-alpha", "other"));
        // By name, `alpha` is found without opening the mis-named duplicate...
        assert!(reg.get("alpha").is_ok());
        // ...which the full listing opens and reports.
        let e = reg.open_all().unwrap_err();
        assert!(
            matches!(e, LawError::DuplicateName { ref name, .. } if name == "alpha"),
            "{e}"
        );
    }

    #[test]
    fn an_unknown_law_names_the_available_laws_and_the_broken_files() {
        let reg = registry("/t-unknown", &["alpha", "broken", "zeta"]);
        let e = reg.get("omega").unwrap_err();
        let msg = e.to_string();
        assert!(
            matches!(&e, LawError::UnknownLaw { broken, .. } if broken.len() == 1),
            "{msg}"
        );
        assert!(
            msg.contains("no law named `omega`")
                && msg.contains("alpha, zeta")
                && msg.contains("libtribo_law_broken")
                && msg.contains("invalid ELF header"),
            "{msg}"
        );
        // An empty registry says so.
        let e = LawRegistry::new().get("omega").unwrap_err().to_string();
        assert!(e.contains("no plugin libraries were found"), "{e}");
    }

    #[test]
    fn open_all_lists_laws_by_name_and_broken_files_in_search_order() {
        let reg = registry("/t-all", &["zeta", "broken", "alpha", "broken_too"]);
        let listing = reg.open_all().expect("no duplicates");
        let names: Vec<&str> = listing.laws.iter().map(|l| l.name()).collect();
        assert_eq!(names, ["alpha", "zeta"]);
        let broken: Vec<String> = listing
            .broken
            .iter()
            .map(|(p, _)| promised_name(p).expect("plugin name"))
            .collect();
        assert_eq!(broken, ["broken", "broken_too"]);
        assert!(listing
            .broken
            .iter()
            .all(|(_, e)| matches!(e, LawError::NotALibrary { .. })));
    }

    #[test]
    fn the_registry_is_shared_by_threads_and_each_file_opened_once() {
        fn assert_sync<T: Sync + Send>() {}
        assert_sync::<LawRegistry>();
        let dir = "/t-threads";
        let reg = registry(dir, &["alpha", "beta"]);
        std::thread::scope(|s| {
            for _ in 0..8 {
                s.spawn(|| {
                    assert_eq!(reg.get("alpha").expect("alpha").name(), "alpha");
                    assert_eq!(reg.get("beta").expect("beta").name(), "beta");
                });
            }
        });
        let mut opened = opened_in(dir);
        opened.sort();
        assert_eq!(opened, ["alpha", "beta"]);
    }

    #[test]
    fn writers_other_than_the_owner_are_reported() {
        // uid 1000, group 1000: the user's private group; group 100: shared.
        assert_eq!(other_writers(0o755, 1000, 1000), None);
        assert_eq!(other_writers(0o700, 1000, 100), None);
        assert_eq!(other_writers(0o777, 1000, 1000), Some("anyone"));
        assert_eq!(other_writers(0o1777, 0, 0), Some("anyone"));
        assert_eq!(other_writers(0o757, 1000, 100), Some("anyone"));
        assert_eq!(other_writers(0o775, 1000, 100), Some("its group"));
        assert_eq!(other_writers(0o775, 1000, 1000), None);
    }

    #[cfg(unix)]
    #[test]
    fn a_plugin_directory_others_can_write_is_warned_about_once() {
        use std::os::unix::fs::PermissionsExt;
        let base = std::env::temp_dir().join(format!("tribo-discover-{}", std::process::id()));
        let open = base.join("open");
        let closed = base.join("closed");
        for (dir, mode) in [(&open, 0o777), (&closed, 0o755)] {
            std::fs::create_dir_all(dir).expect("create");
            std::fs::set_permissions(dir, std::fs::Permissions::from_mode(mode)).expect("chmod");
        }
        // The open directory twice (once by another spelling): one warning.
        let reg = load_paths(&[open.clone(), closed.clone(), open.join(".")]).expect("scans");
        std::fs::remove_dir_all(&base).expect("clean up");
        let w = reg.warnings();
        assert_eq!(w.len(), 1, "{w:?}");
        assert_eq!(
            (w[0].path.as_path(), w[0].mode, w[0].is_dir),
            (open.as_path(), 0o777, true)
        );
        let msg = w[0].to_string();
        assert!(
            msg.contains(&open.display().to_string())
                && msg.contains("0777")
                && msg.contains("run their code as you"),
            "{msg}"
        );
    }
}
