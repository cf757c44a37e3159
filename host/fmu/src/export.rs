//! The `.fmu` archive of a rig with its laws: `modelDescription.xml`, the FMU's library in
//! `binaries/linux64/`, and in `resources/` the rig (`model.toml`, a rig file `tribo run`
//! reads), the interface, the law libraries the rig uses and the `tribo` executable that runs
//! them as the worker. Written whole or not at all (a temporary file renamed into place).

use std::io::Write;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};

use tribo_core::model::RigFile;
use tribo_plugin_api::loader::LawRegistry;
use zip::write::SimpleFileOptions;

use crate::interface::{DriveMode, Interface, Source, MODEL_IDENTIFIER};
use crate::worker::{INTERFACE_FILE, MODEL_FILE, PLUGIN_DIR, WORKER_EXE};
use crate::FmuError;

/// What an export needs.
pub struct Export<'a> {
    /// The rig with its laws attached.
    pub model: &'a RigFile,
    /// Where the laws come from (their descriptions and library files).
    pub registry: &'a LawRegistry,
    /// Which input drives the crank.
    pub drive: DriveMode,
    /// The `tribo` executable shipped as the worker.
    pub worker_exe: &'a Path,
    /// The FMU library (this crate's cdylib, `libtribo_fmu.so`).
    pub fmu_library: &'a Path,
    /// The Tribo version exporting.
    pub tribo_version: &'a str,
}

/// One file of the archive.
struct Entry {
    name: String,
    bytes: Vec<u8>,
    executable: bool,
}

/// Read `path` for the archive, naming it and what it is on failure.
fn read(path: &Path, what: &str) -> Result<Vec<u8>, FmuError> {
    std::fs::read(path)
        .map_err(|e| FmuError::Export(format!("cannot read the {what} {}: {e}", path.display())))
}

/// A GUID from the archive's content (two SipHash-1-3 digests, 128 bits): the same export
/// gives the same GUID, a different rig, law, parameter or build a different one.
fn guid(entries: &[Entry]) -> String {
    use std::hash::{DefaultHasher, Hasher};
    let digest = |salt: u8| {
        let mut h = DefaultHasher::new();
        h.write_u8(salt);
        for e in entries {
            h.write(e.name.as_bytes());
            h.write_u64(e.bytes.len() as u64);
            h.write(&e.bytes);
        }
        h.finish()
    };
    let x = format!("{:016x}{:016x}", digest(1), digest(2));
    format!(
        "{{{}-{}-{}-{}-{}}}",
        &x[..8],
        &x[8..12],
        &x[12..16],
        &x[16..20],
        &x[20..]
    )
}

/// Write the FMU of `e` to `out`; returns its interface.
pub fn export(e: &Export, out: &Path) -> Result<Interface, FmuError> {
    if e.model.drivetrain.is_some() {
        return Err(FmuError::Export(format!(
            "rig `{}` has a [drivetrain]: the FMU integrates the crank train alone, not the chain's degrees of freedom; run the test bed with `tribo run` (its cycle or --steady), or export the rig without its [drivetrain]",
            e.model.name
        )));
    }
    if e.model
        .engine
        .as_ref()
        .is_some_and(|g| g.crankshaft.is_some())
    {
        return Err(FmuError::Export(format!(
            "rig `{}` has an elastic crankshaft ([engine.crankshaft]): the FMU integrates a rigid crank train, not the shaft's degrees of freedom; run it with `tribo run` (its cycle or --steady), or export the rig without [engine.crankshaft]",
            e.model.name
        )));
    }
    // The run the FMU's worker makes of the rig binds here first, so a law or setting it
    // refuses is reported at the export (the oil temperature is the worker's input).
    let oil_c = tribo_core::oil::VALID_RANGE_C.0;
    tribo_core::sim::Simulation::new(
        &crate::dynamic::stepping_model(e.model, e.drive, 0.0, oil_c),
        e.registry,
    )
    .map_err(|err| FmuError::Export(format!("the rig as the FMU runs it: {err}")))?;
    let mut iface = Interface::build(&Source {
        model: e.model,
        registry: e.registry,
        drive: e.drive,
        tribo_version: e.tribo_version,
    })?;
    let model_text = toml::to_string(e.model)
        .map_err(|err| FmuError::Export(format!("the rig cannot be written as TOML: {err}")))?;
    let mut entries = vec![
        Entry {
            name: format!("binaries/linux64/{MODEL_IDENTIFIER}.so"),
            bytes: read(e.fmu_library, "FMU library")?,
            executable: true,
        },
        Entry {
            name: format!("resources/{WORKER_EXE}"),
            bytes: read(e.worker_exe, "worker executable")?,
            executable: true,
        },
        Entry {
            name: format!("resources/{MODEL_FILE}"),
            bytes: model_header(e)
                .into_bytes()
                .into_iter()
                .chain(model_text.into_bytes())
                .collect(),
            executable: false,
        },
    ];
    let mut libraries: Vec<&str> = iface.laws.iter().map(|l| l.library.as_str()).collect();
    libraries.sort_unstable();
    libraries.dedup();
    for slot_law in libraries {
        let law = iface
            .laws
            .iter()
            .find(|l| l.library == slot_law)
            .map(|l| l.law.as_str())
            .unwrap_or_default();
        let path = e
            .registry
            .get(law)
            .map_err(|err| FmuError::Export(err.to_string()))?
            .path()
            .to_path_buf();
        entries.push(Entry {
            name: format!("resources/{PLUGIN_DIR}/{slot_law}"),
            bytes: read(&path, &format!("library of law `{law}`"))?,
            executable: true,
        });
    }
    // The GUID covers everything but the two files that state it.
    iface.guid = guid(&entries);
    let iface_text = toml::to_string(&iface)
        .map_err(|err| FmuError::Export(format!("the interface cannot be written: {err}")))?;
    entries.insert(
        0,
        Entry {
            name: "modelDescription.xml".into(),
            bytes: crate::model_description::write(&iface).into_bytes(),
            executable: false,
        },
    );
    entries.push(Entry {
        name: format!("resources/{INTERFACE_FILE}"),
        bytes: iface_text.into_bytes(),
        executable: false,
    });
    write_archive(&entries, out)?;
    Ok(iface)
}

/// What `tribo fmu export` prints: the file and its interface in brief, in lines of at most
/// [`SUMMARY_COLUMNS`]: each law once with its joints, the rig-level outputs by name and the
/// per-joint ones once, the parameters counted (every one is in `modelDescription.xml`).
pub fn summary(iface: &Interface, out: &Path) -> String {
    use crate::interface::Causality;
    let names = |c: Causality| -> Vec<&str> {
        iface
            .variables
            .iter()
            .filter(|v| v.causality == c)
            .map(|v| v.name.as_str())
            .collect()
    };
    let mut by_law: Vec<(&str, Vec<&str>)> = Vec::new();
    for l in &iface.laws {
        match by_law.iter_mut().find(|(law, _)| *law == l.law) {
            Some((_, joints)) => {
                if !joints.contains(&l.joint.as_str()) {
                    joints.push(&l.joint);
                }
            }
            None => by_law.push((&l.law, vec![&l.joint])),
        }
    }
    let laws: Vec<String> = by_law
        .iter()
        .map(|(law, joints)| format!("{law} on {}", joints.join(" ")))
        .collect();
    // Per-joint outputs (`JOINT.QUANTITY`) once by quantity, with the number of joints.
    let outputs = names(Causality::Output);
    let (rig_level, per_joint): (Vec<&str>, Vec<&str>) =
        outputs.iter().partition(|n| !n.contains('.'));
    let mut quantities: Vec<&str> = Vec::new();
    let mut joints: Vec<&str> = Vec::new();
    for n in &per_joint {
        if let Some((joint, q)) = n.split_once('.') {
            if !quantities.contains(&q) {
                quantities.push(q);
            }
            if !joints.contains(&joint) {
                joints.push(joint);
            }
        }
    }
    let mut output_items: Vec<String> = rig_level.iter().map(|s| s.to_string()).collect();
    if !joints.is_empty() {
        output_items.push(format!(
            "JOINT.{{{}}} for each of {} joints",
            quantities.join(", "),
            joints.len()
        ));
    }
    let params = names(Causality::Parameter);
    let mut text = format!(
        "wrote {} (FMI 2.0 Co-Simulation, linux64, GUID {})\n  rig: {}\n",
        out.display(),
        iface.guid,
        iface.model_name
    );
    text.push_str(&listed("laws", &laws));
    text.push_str(&listed("inputs", &names(Causality::Input)));
    text.push_str(&listed("outputs", &output_items));
    text.push_str(&format!(
        "  parameters: {} (JOINT.LAW.PARAM for every law parameter, and the worker's; each is\n    listed in the FMU's modelDescription.xml)\n",
        params.len()
    ));
    text
}

/// The widest line [`summary`] prints.
pub const SUMMARY_COLUMNS: usize = 100;

/// `  LABEL: a, b, c` over as many lines as [`SUMMARY_COLUMNS`] needs, continuation lines
/// indented; items are never split.
fn listed<T: AsRef<str>>(label: &str, items: &[T]) -> String {
    let mut out = format!("  {label}:");
    let mut width = out.len();
    for (k, item) in items.iter().enumerate() {
        let item = item.as_ref();
        let sep = if k + 1 < items.len() { "," } else { "" };
        let piece = item.chars().count() + sep.len();
        if width + 1 + piece > SUMMARY_COLUMNS && width > 6 {
            out.push_str("\n     ");
            width = 5;
        }
        out.push(' ');
        out.push_str(item);
        out.push_str(sep);
        width += 1 + piece;
    }
    out.push('\n');
    out
}

/// The comment heading `model.toml`: what it is.
fn model_header(e: &Export) -> String {
    format!(
        "# The rig of this FMU with its laws, written by Tribo {} (`tribo fmu export`).\n# A rig file: `tribo run model.toml --steady` runs it as the FMU does at each plateau.\n\n",
        e.tribo_version
    )
}

/// Write `entries` as a zip archive to `out`, whole or not at all.
fn write_archive(entries: &[Entry], out: &Path) -> Result<(), FmuError> {
    let fail = |what: &str, err: &dyn std::fmt::Display| {
        FmuError::Export(format!("{what} {}: {err}", out.display()))
    };
    if out.is_dir() {
        return Err(fail("cannot write the FMU to", &"it is a directory"));
    }
    let dir: PathBuf = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let tmp = tempfile::Builder::new()
        .prefix(".tribo-fmu-")
        .suffix(".tmp")
        .tempfile_in(&dir)
        .map_err(|err| fail("cannot create a temporary file beside", &err))?;
    let mut zip = zip::ZipWriter::new(tmp);
    for entry in entries {
        let options = SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated)
            .last_modified_time(zip::DateTime::default())
            .unix_permissions(if entry.executable { 0o755 } else { 0o644 });
        zip.start_file(entry.name.as_str(), options)
            .map_err(|err| fail("cannot write", &err))?;
        zip.write_all(&entry.bytes)
            .map_err(|err| fail("cannot write", &err))?;
    }
    let tmp = zip.finish().map_err(|err| fail("cannot write", &err))?;
    tmp.as_file()
        .sync_all()
        .map_err(|err| fail("cannot write", &err))?;
    // A temporary file is private (0600); the FMU is a plain readable file.
    std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(0o644))
        .map_err(|err| fail("cannot write", &err))?;
    tmp.persist(out)
        .map_err(|err| fail("cannot write", &err.error))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_guid_follows_the_content() {
        let e = |name: &str, bytes: &[u8]| Entry {
            name: name.into(),
            bytes: bytes.to_vec(),
            executable: false,
        };
        let a = guid(&[e("a", b"1"), e("b", b"2")]);
        assert_eq!(a, guid(&[e("a", b"1"), e("b", b"2")]));
        assert_ne!(a, guid(&[e("a", b"1"), e("b", b"3")]));
        // A byte moved from one file's content to the next file's name is another archive.
        assert_ne!(
            guid(&[e("a", b"12"), e("b", b"")]),
            guid(&[e("a", b"1"), e("2b", b"")])
        );
        assert_eq!(a.len(), 38);
        assert!(a.starts_with('{') && a.ends_with('}'));
        assert_eq!(a.matches('-').count(), 4);
    }
}
