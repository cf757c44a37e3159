//! `tribo new-law`: generate a law plugin from the templates in `host/templates/<language>`: a
//! Rust crate, or a folder with the law in C, C++ or Fortran, a Makefile and a unit test.

use std::fmt;
use std::path::{Component, Path, PathBuf};
use std::str::FromStr;

/// Why a scaffold could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ScaffoldError {
    /// The name is not usable as a law and crate name.
    #[error("`{0}` is not a valid law name: use lowercase letters, digits and single hyphens, starting with a letter (e.g. `my-law`)")]
    BadName(String),
    /// No Tribo checkout above the starting directory (a Rust law needs its plugin-api).
    #[error("no Tribo workspace (a Cargo.toml beside plugin-api/) found in `{0}` or above; a Rust law is built against the checkout's plugin-api, so run `tribo new-law` inside a Tribo checkout (laws in C, C++ or Fortran can be generated anywhere)")]
    NoWorkspace(PathBuf),
    /// Refuse to overwrite.
    #[error("`{0}` already exists; choose another name or --dir")]
    Exists(PathBuf),
    /// A C, C++ or Fortran folder would land in the workspace's `plugins/`, whose every
    /// directory cargo takes for a crate.
    #[error("`{0}` would be inside the workspace's plugins/, where cargo takes every directory for a Rust crate (and would stop building); generate a C, C++ or Fortran law elsewhere with --dir")]
    InPluginsDir(PathBuf),
    /// File system error.
    #[error("cannot write `{path}`: {source}")]
    Io {
        /// Path.
        path: PathBuf,
        /// OS error.
        source: std::io::Error,
    },
}

/// The language of a generated law.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lang {
    /// A cargo crate using `tribo_plugin_api::export_law!` (the Rust ABI).
    Rust,
    /// A C source, Makefile and test main (the C ABI of `tribo_law.h`).
    C,
    /// A C++ class exported through `extern "C"` functions that catch every exception.
    Cpp,
    /// A Fortran module using the `tribo_law` interface module (`iso_c_binding`, `bind(c)`).
    Fortran,
}

impl Lang {
    /// Every language, in the order the help lists them.
    pub const ALL: [Lang; 4] = [Lang::Rust, Lang::C, Lang::Cpp, Lang::Fortran];

    /// The name on the command line (`--lang`).
    pub fn as_str(self) -> &'static str {
        match self {
            Lang::Rust => "rust",
            Lang::C => "c",
            Lang::Cpp => "cpp",
            Lang::Fortran => "fortran",
        }
    }
}

impl fmt::Display for Lang {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Lang {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "rust" => Ok(Lang::Rust),
            "c" => Ok(Lang::C),
            "cpp" | "c++" => Ok(Lang::Cpp),
            "fortran" => Ok(Lang::Fortran),
            other => Err(format!(
                "`{other}` is not a language tribo can generate a law in: expected rust, c, cpp or fortran"
            )),
        }
    }
}

/// What was generated.
#[derive(Debug)]
pub struct Scaffold {
    /// The law's directory (a crate for Rust, a Makefile folder otherwise).
    pub dir: PathBuf,
    /// The law's language.
    pub lang: Lang,
    /// The law's name.
    pub name: String,
    /// Cargo package name (Rust only).
    pub crate_name: Option<String>,
    /// File name of the built library.
    pub library_file: String,
    /// Whether the crate is a member of the Tribo workspace (never for C, C++ or Fortran).
    pub workspace_member: bool,
    /// Where the Makefile takes `tribo_law.h` (and `tribo_law.f90`) from (not for Rust): the
    /// checkout's `plugin-api/include`, or a copy in the law's folder when there is no checkout.
    pub include_dir: Option<PathBuf>,
}

impl Scaffold {
    /// The commands that test, build and check the new law, one line each, for the user.
    pub fn next_steps(&self) -> Vec<String> {
        let dir = self.dir.display();
        let (name, file) = (&self.name, &self.library_file);
        match &self.crate_name {
            Some(krate) => {
                let mut steps = vec![
                    format!("test:  cargo test -p {krate}"),
                    format!("build: cargo build --release -p {krate}"),
                ];
                if self.workspace_member {
                    steps.push(format!(
                        "the library {file} lands in target/release/, where tribo finds it"
                    ));
                    steps.push(format!("check: tribo check-law target/release/{file}"));
                    steps.push(format!(
                        "use:   tribo run crf250r-motored --steady --law piston={name}"
                    ));
                } else {
                    steps.push(format!(
                        "then put {file} in a directory on TRIBO_PLUGIN_PATH or pass --plugin"
                    ));
                }
                steps
            }
            None => {
                let mut steps = vec![
                    format!("test:  make -C {dir} test"),
                    format!("build: make -C {dir}   (builds {file})"),
                    format!("check: make -C {dir} check   (tribo check-law on {file})"),
                    format!(
                        "use:   tribo run crf250r-motored --steady --plugin {dir}/{file} --law piston={name}"
                    ),
                ];
                if self
                    .include_dir
                    .as_ref()
                    .is_some_and(|inc| inc.starts_with(&self.dir))
                {
                    steps.push(format!(
                        "no Tribo checkout here: tribo_law.h and tribo_law.f90 were copied into {dir}/include"
                    ));
                }
                steps
            }
        }
    }
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

/// A path make can take as a variable's value: UTF-8, without blanks or the characters make
/// or the shell would interpret.
fn make_safe(path: &Path) -> Option<&str> {
    path.to_str().filter(|s| {
        !s.is_empty()
            && !s
                .chars()
                .any(|c| c.is_whitespace() || "$#:;=\\\"'`*?[]()&|<>%".contains(c))
    })
}

/// One generated file: its path in the law's directory and its template.
type Template = (String, &'static str);

/// The templates of `lang` and where each goes (`snake` is the law name with `_` for `-`).
fn templates(lang: Lang, snake: &str) -> Vec<Template> {
    let f = |path: &str, text: &'static str| (path.to_string(), text);
    match lang {
        Lang::Rust => vec![
            f(
                "Cargo.toml",
                include_str!("../templates/rust/Cargo.toml.tmpl"),
            ),
            f("src/lib.rs", include_str!("../templates/rust/lib.rs.tmpl")),
            f(
                "README.md",
                include_str!("../templates/rust/README.md.tmpl"),
            ),
        ],
        Lang::C => vec![
            f("Makefile", include_str!("../templates/c/Makefile.tmpl")),
            (
                format!("{snake}.c"),
                include_str!("../templates/c/law.c.tmpl"),
            ),
            (
                format!("test_{snake}.c"),
                include_str!("../templates/c/test.c.tmpl"),
            ),
            f("README.md", include_str!("../templates/c/README.md.tmpl")),
            f(".gitignore", include_str!("../templates/c/gitignore.tmpl")),
        ],
        Lang::Cpp => vec![
            f("Makefile", include_str!("../templates/cpp/Makefile.tmpl")),
            (
                format!("{snake}.hpp"),
                include_str!("../templates/cpp/law.hpp.tmpl"),
            ),
            (
                format!("{snake}.cpp"),
                include_str!("../templates/cpp/law.cpp.tmpl"),
            ),
            (
                format!("test_{snake}.cpp"),
                include_str!("../templates/cpp/test.cpp.tmpl"),
            ),
            f("README.md", include_str!("../templates/cpp/README.md.tmpl")),
            f(
                ".gitignore",
                include_str!("../templates/cpp/gitignore.tmpl"),
            ),
        ],
        Lang::Fortran => vec![
            f(
                "Makefile",
                include_str!("../templates/fortran/Makefile.tmpl"),
            ),
            (
                format!("{snake}.f90"),
                include_str!("../templates/fortran/law.f90.tmpl"),
            ),
            (
                format!("test_{snake}.f90"),
                include_str!("../templates/fortran/test.f90.tmpl"),
            ),
            f(
                "README.md",
                include_str!("../templates/fortran/README.md.tmpl"),
            ),
            f(
                ".gitignore",
                include_str!("../templates/fortran/gitignore.tmpl"),
            ),
        ],
    }
}

/// The contract files a C, C++ or Fortran law is built against, copied into its folder when
/// `tribo new-law` runs outside a Tribo checkout.
const CONTRACT_FILES: [(&str, &str); 2] = [
    (
        "tribo_law.h",
        include_str!("../../plugin-api/include/tribo_law.h"),
    ),
    (
        "tribo_law.f90",
        include_str!("../../plugin-api/include/tribo_law.f90"),
    ),
];

/// Generate law `name` in `lang` into `dir`, starting the workspace search at `cwd`. The
/// default directory is the workspace's `plugins/` for Rust (the new crate becomes a member),
/// and `cwd` for C, C++ and Fortran. `tribo_exe` is written into the Makefile for `make check`.
pub fn new_law(
    name: &str,
    lang: Lang,
    dir: Option<&Path>,
    cwd: &Path,
    tribo_exe: &Path,
) -> Result<Scaffold, ScaffoldError> {
    if !valid_name(name) {
        return Err(ScaffoldError::BadName(name.into()));
    }
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| ScaffoldError::Io { path, source }
    };
    let cwd = absolute(cwd).map_err(io(cwd))?;
    let ws = find_workspace(&cwd);
    let parent = match (dir, &ws, lang) {
        (Some(d), _, _) => absolute(&cwd.join(d)).map_err(io(d))?,
        (None, Some(ws), Lang::Rust) => ws.join("plugins"),
        (None, None, Lang::Rust) => return Err(ScaffoldError::NoWorkspace(cwd)),
        (None, _, _) => cwd.clone(),
    };
    let law_dir = parent.join(name);
    if law_dir.exists() {
        return Err(ScaffoldError::Exists(law_dir));
    }
    if lang != Lang::Rust && ws.as_ref().is_some_and(|ws| parent == ws.join("plugins")) {
        return Err(ScaffoldError::InPluginsDir(law_dir));
    }
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
    let library_file = tribo_plugin_api::loader::plugin_file_name(&lib);

    // Rust: a crate with a path dependency on the checkout's plugin-api. The workspace takes
    // every directory under plugins/ as a member; anywhere else the crate is its own workspace
    // so Cargo does not complain about an unlisted member.
    let (crate_name, workspace_member, api_path) = match lang {
        Lang::Rust => {
            let ws = ws
                .as_ref()
                .ok_or_else(|| ScaffoldError::NoWorkspace(cwd.clone()))?;
            (
                Some(format!("tribo-law-{name}")),
                parent == ws.join("plugins"),
                relative(&law_dir, &ws.join("plugin-api")),
            )
        }
        _ => (None, false, String::new()),
    };
    // C, C++, Fortran: the Makefile points at the checkout's plugin-api/include, so a rebuild
    // follows the checkout; without a checkout (or at a path make cannot hold) the contract
    // files are copied into the folder.
    let checkout_include = ws
        .as_ref()
        .map(|ws| ws.join("plugin-api/include"))
        .filter(|inc| make_safe(inc).is_some());
    let (include_dir, include_text, copy_contract) = match (lang, checkout_include) {
        (Lang::Rust, _) => (None, String::new(), false),
        (_, Some(inc)) => {
            let text = make_safe(&inc).unwrap_or_default().to_string();
            (Some(inc), text, false)
        }
        (_, None) => (Some(law_dir.join("include")), "include".to_string(), true),
    };
    let tribo = make_safe(tribo_exe).unwrap_or("tribo").to_string();

    let fill = |t: &str| {
        t.replace("{{name}}", name)
            .replace("{{snake}}", &snake)
            .replace("{{SNAKE}}", &snake.to_ascii_uppercase())
            .replace("{{crate}}", crate_name.as_deref().unwrap_or_default())
            .replace("{{lib}}", &lib)
            .replace("{{type}}", &type_name)
            .replace("{{file}}", &library_file)
            .replace("{{api_path}}", &api_path)
            .replace("{{include}}", &include_text)
            .replace("{{tribo}}", &tribo)
            .replace(
                "{{workspace_table}}",
                if workspace_member {
                    ""
                } else {
                    "\n# Not a member of the Tribo workspace: this crate is its own.\n[workspace]\n"
                },
            )
    };
    let mut files: Vec<(PathBuf, String)> = templates(lang, &snake)
        .into_iter()
        .map(|(rel, template)| (law_dir.join(rel), fill(template)))
        .collect();
    if copy_contract {
        files.extend(
            CONTRACT_FILES
                .iter()
                .map(|(file, text)| (law_dir.join("include").join(file), text.to_string())),
        );
    }
    for (path, text) in files {
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(io(parent))?;
        }
        std::fs::write(&path, text).map_err(io(&path))?;
    }
    Ok(Scaffold {
        dir: law_dir,
        lang,
        name: name.to_string(),
        crate_name,
        library_file,
        workspace_member,
        include_dir,
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

    #[test]
    fn languages_parse_from_their_names_and_nothing_else() {
        for lang in Lang::ALL {
            assert_eq!(lang.as_str().parse::<Lang>(), Ok(lang));
        }
        assert_eq!("c++".parse::<Lang>(), Ok(Lang::Cpp));
        let e = "python".parse::<Lang>().unwrap_err();
        assert!(e.contains("rust, c, cpp or fortran"), "{e}");
    }

    #[test]
    fn paths_make_cannot_hold_are_refused() {
        assert_eq!(
            make_safe(Path::new("/home/a/tribo/plugin-api/include")),
            Some("/home/a/tribo/plugin-api/include")
        );
        for bad in ["/home/a b/x", "/x/$(rm)", "/x#y", "/c:/x", ""] {
            assert_eq!(make_safe(Path::new(bad)), None, "{bad}");
        }
    }

    #[test]
    fn a_c_law_is_not_put_among_the_workspace_crates() {
        let tmp = std::env::temp_dir().join(format!("tribo-scaffold-ws-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&tmp);
        std::fs::create_dir_all(tmp.join("plugin-api")).expect("mkdir");
        std::fs::create_dir_all(tmp.join("plugins")).expect("mkdir");
        std::fs::write(tmp.join("Cargo.toml"), "[workspace]\n").expect("write");
        std::fs::write(tmp.join("plugin-api/Cargo.toml"), "").expect("write");
        let exe = Path::new("tribo");
        let e = new_law("x", Lang::C, None, &tmp.join("plugins"), exe).unwrap_err();
        assert!(matches!(e, ScaffoldError::InPluginsDir(_)), "{e}");
        let e = new_law("x", Lang::Fortran, Some(Path::new("plugins")), &tmp, exe).unwrap_err();
        assert!(matches!(e, ScaffoldError::InPluginsDir(_)), "{e}");
        assert!(!tmp.join("plugins/x").exists());
        // Beside the plugins, in the checkout, is fine.
        let s = new_law("x", Lang::Cpp, None, &tmp, exe).expect("generates");
        assert_eq!(s.dir, tmp.join("x"));
        assert_eq!(s.include_dir, Some(tmp.join("plugin-api/include")));
        let _ = std::fs::remove_dir_all(&tmp);
    }

    #[test]
    fn every_template_placeholder_is_filled() {
        let tmp = std::env::temp_dir().join(format!("tribo-scaffold-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&tmp);
        for lang in [Lang::C, Lang::Cpp, Lang::Fortran] {
            let name = format!("x-{lang}");
            let s = new_law(&name, lang, Some(&tmp), &tmp, Path::new("/opt/tribo/tribo"))
                .expect("generates");
            for entry in std::fs::read_dir(&s.dir).expect("dir") {
                let path = entry.expect("entry").path();
                if path.is_file() {
                    let text = std::fs::read_to_string(&path).expect("read");
                    assert!(!text.contains("{{"), "{}: {text}", path.display());
                }
            }
            // Outside a checkout the contract files are copied beside the law.
            assert_eq!(s.include_dir, Some(s.dir.join("include")));
            assert!(s.dir.join("include/tribo_law.h").is_file());
            let makefile = std::fs::read_to_string(s.dir.join("Makefile")).expect("Makefile");
            assert!(
                makefile.contains("TRIBO_INCLUDE ?= include\n"),
                "{makefile}"
            );
            assert!(
                makefile.contains("TRIBO ?= /opt/tribo/tribo\n"),
                "{makefile}"
            );
        }
        let _ = std::fs::remove_dir_all(&tmp);
    }
}
