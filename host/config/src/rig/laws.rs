//! `--law JOINT=LAW[:PARAMS.toml]`: laws attached to a rig's joints from the command line.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::{expand_joint, line_col, LawOrigin, LawRef, Rig, RigError, Source, JOINT_NAMES};
use crate::files::read_text;

/// One `--law JOINT=LAW[:PARAMS_TOML_FILE]` argument, parsed.
#[derive(Debug, Clone)]
pub struct LawArg {
    /// The joint.
    pub joint: String,
    /// The law and its parameters.
    pub law: LawRef,
    /// The argument and its parameter file, for locating errors about the law.
    pub origin: LawOrigin,
}

/// Parse one `--law JOINT=LAW[:PARAMS_TOML_FILE]` argument into the joint and the law; the
/// parameter file is read (capped, regular files only) and parsed here.
pub fn parse_law_arg(arg: &str) -> Result<LawArg, RigError> {
    let err = |message: String| RigError {
        file: PathBuf::from("--law"),
        line: None,
        column: None,
        field: arg.to_string(),
        message,
    };
    let (joint, spec) = arg
        .split_once('=')
        .ok_or_else(|| err("expected JOINT=LAW or JOINT=LAW:PARAMS.toml".into()))?;
    if !crate::lawset::is_joint_pattern(joint) {
        return Err(err(format!(
            "unknown joint `{joint}`; the rig's joints are {} (an engine's: main_1 .. main_n, big_end_k, small_end_k, piston_k; groups: main_*, big_end_*, small_end_*, piston_*)",
            JOINT_NAMES.join(", ")
        )));
    }
    let (law, params, source) = match spec.split_once(':') {
        Some((l, file)) => {
            let text = read_text(Path::new(file))
                .map_err(|e| err(format!("the parameter file `{file}` {e}")))?;
            let table: toml::Table = toml::from_str(&text).map_err(|e: toml::de::Error| {
                let at = e.span().map(|s| line_col(&text, s.start));
                let place = at.map_or(String::new(), |(l, c)| format!(":{l}:{c}"));
                err(format!("{file}{place}: {}", e.message()))
            })?;
            let source = Source {
                path: PathBuf::from(file),
                text,
            };
            (l, table, Some(Arc::new(source)))
        }
        None => (spec, toml::Table::new(), None),
    };
    Ok(LawArg {
        joint: joint.to_string(),
        law: LawRef {
            law: law.to_string(),
            params,
        },
        origin: LawOrigin::Arg {
            arg: arg.to_string(),
            params: source,
        },
    })
}

/// Apply `--law JOINT=LAW[:PARAMS_TOML_FILE]` arguments: the first for a joint replaces the
/// rig's laws there, later ones add.
pub fn attach_laws(rig: &mut Rig, args: &[String]) -> Result<(), RigError> {
    let mut replaced: Vec<String> = Vec::new();
    for arg in args {
        let LawArg { joint, law, origin } = parse_law_arg(arg)?;
        // A group or, on an engine, a single-cylinder name: every joint it names.
        let names = expand_joint(&joint, &rig.file);
        if names.is_empty() {
            return Err(RigError {
                file: PathBuf::from("--law"),
                line: None,
                column: None,
                field: arg.clone(),
                message: format!(
                    "the rig `{}` has no joint `{joint}`; its joints are {}",
                    rig.file.name,
                    match &rig.file.engine {
                        Some(e) => e.joint_names().join(", "),
                        None => JOINT_NAMES.join(", "),
                    }
                ),
            });
        }
        for name in names {
            let laws = match rig.file.engine.as_mut() {
                Some(e) => e.laws.entry(name.clone()).or_default(),
                None => match rig.file.joints.get_mut(&name) {
                    Some(j) => &mut j.laws,
                    None => continue,
                },
            };
            if !replaced.contains(&name) {
                laws.clear();
                rig.law_origins.retain(|(n, _), _| *n != name);
                replaced.push(name.clone());
            }
            rig.law_origins
                .insert((name.clone(), laws.len()), origin.clone());
            laws.push(law.clone());
            rig.overridden.push(format!("joints.{name}.laws"));
        }
    }
    Ok(())
}
