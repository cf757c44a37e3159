//! Rigs, law sets and measurement data compiled into the binary, so the main job runs from any
//! directory. Files on disk always win over a bundled file of the same name.

/// Bundled rigs: file name and text.
const RIGS: &[(&str, &str)] = &[
    (
        "crf250r-motored.toml",
        include_str!("../../../rigs/crf250r-motored.toml"),
    ),
    (
        "crf250r-light-rod.toml",
        include_str!("../../../rigs/crf250r-light-rod.toml"),
    ),
    (
        "reference-frictionless.toml",
        include_str!("../../../rigs/reference-frictionless.toml"),
    ),
    (
        "crf250r-compression.toml",
        include_str!("../../../rigs/crf250r-compression.toml"),
    ),
    (
        "crf250r-fired.toml",
        include_str!("../../../rigs/crf250r-fired.toml"),
    ),
    (
        "crf250r-vented.toml",
        include_str!("../../../rigs/crf250r-vented.toml"),
    ),
    (
        "crf250r-testbed.toml",
        include_str!("../../../rigs/crf250r-testbed.toml"),
    ),
    (
        "inline4-4b11.toml",
        include_str!("../../../rigs/inline4-4b11.toml"),
    ),
    (
        "inline4-4b11-frictionless.toml",
        include_str!("../../../rigs/inline4-4b11-frictionless.toml"),
    ),
    (
        "inline4-4b11-vented.toml",
        include_str!("../../../rigs/inline4-4b11-vented.toml"),
    ),
    ("vtwin-90.toml", include_str!("../../../rigs/vtwin-90.toml")),
    (
        "vtwin-90-frictionless.toml",
        include_str!("../../../rigs/vtwin-90-frictionless.toml"),
    ),
];

/// Bundled law sets.
const LAWSETS: &[(&str, &str)] = &[
    (
        "fedem-baseline.toml",
        include_str!("../../../rigs/lawsets/fedem-baseline.toml"),
    ),
    (
        "stribeck-duty.toml",
        include_str!("../../../rigs/lawsets/stribeck-duty.toml"),
    ),
    (
        "mixed-film.toml",
        include_str!("../../../rigs/lawsets/mixed-film.toml"),
    ),
    (
        "physical-bearings.toml",
        include_str!("../../../rigs/lawsets/physical-bearings.toml"),
    ),
    (
        "4b11-physical.toml",
        include_str!("../../../rigs/lawsets/4b11-physical.toml"),
    ),
    (
        "4b11-physical-tight.toml",
        include_str!("../../../rigs/lawsets/4b11-physical-tight.toml"),
    ),
    (
        "4b11-physical-loose.toml",
        include_str!("../../../rigs/lawsets/4b11-physical-loose.toml"),
    ),
    (
        "crf250r-physical.toml",
        include_str!("../../../rigs/lawsets/crf250r-physical.toml"),
    ),
];

/// Bundled data files.
const DATA: &[(&str, &str)] = &[
    (
        "crf250r-measured.csv",
        include_str!("../../../rigs/data/crf250r-measured.csv"),
    ),
    (
        "fedem-tuned.csv",
        include_str!("../../../rigs/data/fedem-tuned.csv"),
    ),
    (
        "fedem-light-rod.csv",
        include_str!("../../../rigs/data/fedem-light-rod.csv"),
    ),
    (
        "crf250r-fired-synthetic.csv",
        include_str!("../../../rigs/data/crf250r-fired-synthetic.csv"),
    ),
];

/// The default rig of the study commands.
pub const DEFAULT_RIG: &str = "crf250r-motored.toml";
/// The default measurement data.
pub const DEFAULT_DATA: &str = "crf250r-measured.csv";
/// The default law sets compared.
pub const DEFAULT_LAWSETS: [&str; 3] = ["fedem-baseline", "stribeck-duty", "mixed-film"];

/// `name` with a `.toml`/`.csv` suffix as it is stored (accepts `crf250r-motored` too).
pub fn file_name(name: &str) -> String {
    std::path::Path::new(name)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| name.to_string())
}

fn find(list: &[(&'static str, &'static str)], name: &str, ext: &str) -> Option<&'static str> {
    let n = file_name(name);
    let with_ext = if n.ends_with(ext) {
        n
    } else {
        format!("{n}{ext}")
    };
    list.iter().find(|(f, _)| *f == with_ext).map(|(_, t)| *t)
}

/// A bundled rig by name.
pub fn rig(name: &str) -> Option<&'static str> {
    find(RIGS, name, ".toml")
}

/// A bundled law set by name.
pub fn lawset(name: &str) -> Option<&'static str> {
    find(LAWSETS, name, ".toml")
}

/// A bundled data file by name.
pub fn data(name: &str) -> Option<&'static str> {
    find(DATA, name, ".csv")
}

/// Names of the bundled rigs, for messages.
pub fn rig_names() -> Vec<&'static str> {
    RIGS.iter().map(|(n, _)| *n).collect()
}

/// Names of the bundled law sets, for messages.
pub fn lawset_names() -> Vec<&'static str> {
    LAWSETS
        .iter()
        .map(|(n, _)| n.trim_end_matches(".toml"))
        .collect()
}

/// Names of the bundled data files, for messages.
pub fn data_names() -> Vec<&'static str> {
    DATA.iter().map(|(n, _)| *n).collect()
}
