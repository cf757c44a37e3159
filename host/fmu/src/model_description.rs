//! `modelDescription.xml` (FMI 2.0, Co-Simulation) written from an [`Interface`]: the
//! variables with their units, the unit definitions (SI base-unit exponents, rpm and degrees as
//! display units), the enumeration types of word parameters, and the model structure.

use std::fmt::Write as _;

use crate::interface::{Causality, Interface, Kind, Variability, MODEL_IDENTIFIER};

/// The SI base units FMI 2.0 knows, in its attribute names.
const BASE: [&str; 8] = ["kg", "m", "s", "A", "K", "mol", "cd", "rad"];

/// A unit's exponents of [`BASE`], with the factor and offset to SI.
#[derive(Debug, Clone, PartialEq)]
struct BaseUnit {
    exponents: [i32; 8],
    factor: f64,
    offset: f64,
}

/// The SI exponents of one unit symbol.
fn symbol(s: &str) -> Option<[i32; 8]> {
    Some(match s {
        "kg" => [1, 0, 0, 0, 0, 0, 0, 0],
        "m" => [0, 1, 0, 0, 0, 0, 0, 0],
        "s" => [0, 0, 1, 0, 0, 0, 0, 0],
        "K" => [0, 0, 0, 0, 1, 0, 0, 0],
        "rad" => [0, 0, 0, 0, 0, 0, 0, 1],
        "N" => [1, 1, -2, 0, 0, 0, 0, 0],
        "Pa" => [1, -1, -2, 0, 0, 0, 0, 0],
        "J" => [1, 2, -2, 0, 0, 0, 0, 0],
        "W" => [1, 2, -3, 0, 0, 0, 0, 0],
        "Hz" => [0, 0, -1, 0, 0, 0, 0, 0],
        "1" => [0; 8],
        _ => return None,
    })
}

/// The base unit of a unit in Modelica syntax (`N.m.s/rad`, `1/m`, `degC`); `None` when a
/// symbol is not known (the unit is then declared without one).
fn base_unit(unit: &str) -> Option<BaseUnit> {
    if unit == "degC" {
        let mut exponents = [0; 8];
        exponents[4] = 1;
        return Some(BaseUnit {
            exponents,
            factor: 1.0,
            offset: 273.15,
        });
    }
    let (num, den) = unit.split_once('/').unwrap_or((unit, ""));
    let mut exponents = [0; 8];
    for (part, sign) in [(num, 1), (den, -1)] {
        for s in part.split('.').filter(|s| !s.is_empty()) {
            let e = symbol(s)?;
            for (a, b) in exponents.iter_mut().zip(e) {
                *a += sign * b;
            }
        }
    }
    Some(BaseUnit {
        exponents,
        factor: 1.0,
        offset: 0.0,
    })
}

/// Display units offered for a unit: rpm for rad/s, degrees for rad.
fn display_units(unit: &str) -> &'static [(&'static str, f64)] {
    match unit {
        "rad/s" => &[("rpm", 30.0 / std::f64::consts::PI)],
        "rad" => &[("deg", 180.0 / std::f64::consts::PI)],
        _ => &[],
    }
}

/// `s` with XML's special characters escaped, for an attribute value.
fn xml(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\n' | '\r' | '\t' => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// A number as XML writes it: the shortest text that reads back to the same double.
fn num(x: f64) -> String {
    format!("{x:?}")
}

/// The whole `modelDescription.xml` of `iface`.
pub fn write(iface: &Interface) -> String {
    let mut s = String::new();
    // Writing into a String cannot fail.
    let _ = write_into(&mut s, iface);
    s
}

fn write_into(s: &mut String, iface: &Interface) -> std::fmt::Result {
    writeln!(s, r#"<?xml version="1.0" encoding="UTF-8"?>"#)?;
    writeln!(
        s,
        r#"<fmiModelDescription fmiVersion="2.0" modelName="{}" guid="{}" description="{}" generationTool="Tribo {}" variableNamingConvention="structured" numberOfEventIndicators="0">"#,
        xml(&iface.model_name),
        xml(&iface.guid),
        xml(&iface.description),
        xml(&iface.tribo_version)
    )?;
    writeln!(
        s,
        r#"  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" needsExecutionTool="false" canHandleVariableCommunicationStepSize="true" canInterpolateInputs="false" maxOutputDerivativeOrder="0" canRunAsynchronuously="false" canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="true" canGetAndSetFMUstate="true" canSerializeFMUstate="true" providesDirectionalDerivative="false"/>"#
    )?;
    units(s, iface)?;
    types(s, iface)?;
    writeln!(s, "  <LogCategories>")?;
    for (name, what) in crate::log::CATEGORIES {
        writeln!(
            s,
            r#"    <Category name="{name}" description="{}"/>"#,
            xml(what)
        )?;
    }
    writeln!(s, "  </LogCategories>")?;
    writeln!(
        s,
        r#"  <DefaultExperiment startTime="0.0" stopTime="1.0" stepSize="0.0001"/>"#
    )?;
    writeln!(s, "  <ModelVariables>")?;
    for (vr, v) in iface.variables.iter().enumerate() {
        variable(s, vr, v)?;
    }
    writeln!(s, "  </ModelVariables>")?;
    writeln!(s, "  <ModelStructure>")?;
    let outputs: Vec<(usize, bool)> = iface
        .variables
        .iter()
        .enumerate()
        .filter(|(_, v)| v.causality == Causality::Output)
        .map(|(i, v)| (i + 1, v.variability == Variability::Constant))
        .collect();
    // A constant output's value is its start value (initial "exact"): no initial unknown.
    for (section, constants) in [("Outputs", true), ("InitialUnknowns", false)] {
        writeln!(s, "    <{section}>")?;
        for (i, constant) in &outputs {
            if constants || !constant {
                writeln!(s, r#"      <Unknown index="{i}"/>"#)?;
            }
        }
        writeln!(s, "    </{section}>")?;
    }
    writeln!(s, "  </ModelStructure>")?;
    writeln!(s, "</fmiModelDescription>")
}

/// `<UnitDefinitions>`: every unit a variable uses, once, sorted.
fn units(s: &mut String, iface: &Interface) -> std::fmt::Result {
    let mut names: Vec<&str> = iface
        .variables
        .iter()
        .filter_map(|v| match &v.kind {
            Kind::Real { unit, .. } => unit.as_deref(),
            _ => None,
        })
        .collect();
    names.sort_unstable();
    names.dedup();
    if names.is_empty() {
        return Ok(());
    }
    writeln!(s, "  <UnitDefinitions>")?;
    for name in names {
        write!(s, r#"    <Unit name="{}">"#, xml(name))?;
        if let Some(b) = base_unit(name) {
            write!(s, "<BaseUnit")?;
            for (sym, e) in BASE.iter().zip(b.exponents) {
                if e != 0 {
                    write!(s, r#" {sym}="{e}""#)?;
                }
            }
            if b.factor != 1.0 {
                write!(s, r#" factor="{}""#, num(b.factor))?;
            }
            if b.offset != 0.0 {
                write!(s, r#" offset="{}""#, num(b.offset))?;
            }
            write!(s, "/>")?;
        }
        for (display, factor) in display_units(name) {
            write!(
                s,
                r#"<DisplayUnit name="{display}" factor="{}"/>"#,
                num(*factor)
            )?;
        }
        writeln!(s, "</Unit>")?;
    }
    writeln!(s, "  </UnitDefinitions>")
}

/// `<TypeDefinitions>`: the enumerations of word parameters, once per type name.
fn types(s: &mut String, iface: &Interface) -> std::fmt::Result {
    let mut done: Vec<&str> = Vec::new();
    for v in &iface.variables {
        if let Kind::Enumeration {
            type_name, items, ..
        } = &v.kind
        {
            if done.contains(&type_name.as_str()) {
                continue;
            }
            if done.is_empty() {
                writeln!(s, "  <TypeDefinitions>")?;
            }
            done.push(type_name);
            writeln!(s, r#"    <SimpleType name="{}">"#, xml(type_name))?;
            writeln!(s, "      <Enumeration>")?;
            for (i, item) in items.iter().enumerate() {
                writeln!(
                    s,
                    r#"        <Item name="{}" value="{}"/>"#,
                    xml(item),
                    i + 1
                )?;
            }
            writeln!(s, "      </Enumeration>")?;
            writeln!(s, "    </SimpleType>")?;
        }
    }
    if !done.is_empty() {
        writeln!(s, "  </TypeDefinitions>")?;
    }
    Ok(())
}

/// One `<ScalarVariable>`.
fn variable(s: &mut String, vr: usize, v: &crate::interface::Variable) -> std::fmt::Result {
    let causality = match v.causality {
        Causality::Input => "input",
        Causality::Output => "output",
        Causality::Parameter => "parameter",
    };
    let variability = match v.variability {
        Variability::Continuous => "continuous",
        Variability::Tunable => "tunable",
        Variability::Fixed => "fixed",
        Variability::Constant => "constant",
    };
    writeln!(
        s,
        r#"    <ScalarVariable name="{}" valueReference="{vr}" description="{}" causality="{causality}" variability="{variability}">"#,
        xml(&v.name),
        xml(&v.description)
    )?;
    match &v.kind {
        Kind::Real {
            start,
            unit,
            min,
            max,
        } => {
            write!(s, "      <Real")?;
            if let Some(u) = unit {
                write!(s, r#" unit="{}""#, xml(u))?;
                if let Some((d, _)) = display_units(u).first() {
                    write!(s, r#" displayUnit="{d}""#)?;
                }
            }
            for (attr, x) in [("min", min), ("max", max), ("start", start)] {
                if let Some(x) = x {
                    write!(s, r#" {attr}="{}""#, num(*x))?;
                }
            }
            writeln!(s, "/>")?;
        }
        Kind::Boolean { start } => writeln!(s, r#"      <Boolean start="{start}"/>"#)?,
        Kind::Enumeration {
            start, type_name, ..
        } => writeln!(
            s,
            r#"      <Enumeration declaredType="{}" start="{start}"/>"#,
            xml(type_name)
        )?,
    }
    writeln!(s, "    </ScalarVariable>")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base_units_are_the_si_exponents_of_the_symbols() {
        let b = |u: &str| base_unit(u).map(|b| b.exponents);
        // N m = kg m^2 s^-2; N m s/rad = kg m^2 s^-1 rad^-1; N s/m = kg s^-1.
        assert_eq!(b("N.m"), Some([1, 2, -2, 0, 0, 0, 0, 0]));
        assert_eq!(b("N.m.s/rad"), Some([1, 2, -1, 0, 0, 0, 0, -1]));
        assert_eq!(b("N.s/m"), Some([1, 0, -1, 0, 0, 0, 0, 0]));
        assert_eq!(b("1/m"), Some([0, -1, 0, 0, 0, 0, 0, 0]));
        assert_eq!(b("rad/s"), Some([0, 0, -1, 0, 0, 0, 0, 1]));
        assert_eq!(b("furlong"), None);
        let c = base_unit("degC").expect("known");
        assert_eq!((c.exponents[4], c.factor, c.offset), (1, 1.0, 273.15));
    }

    #[test]
    fn attribute_text_is_escaped() {
        assert_eq!(
            xml(r#"a<b & "c">'d'"#),
            "a&lt;b &amp; &quot;c&quot;&gt;&apos;d&apos;"
        );
    }
}
