//! `modelDescription.xml`, generated from the variable table ([`crate::vars`]), the
//! units ([`crate::units`]) and what the FMU runs ([`Spec`]): no list of variables is
//! kept by hand.
//!
//! The instantiation token is a digest of the description itself (rendered with an
//! empty token): the binary recomputes it at instantiation from the resources it loads,
//! so a description that does not match its binary or resources is refused, not run.

use std::collections::BTreeSet;
use std::fmt::Write as _;

use simrod_io::sha256::hex_digest;

use crate::instance::Values;
use crate::spec::Spec;
use crate::units::{base_unit, DIMENSIONLESS};
use crate::vars::{Choice, Input, Var, SET_POINT_RANGE};

/// The model identifier: the binary's name and the function prefix's owner.
pub const MODEL_IDENTIFIER: &str = "simrod";

/// Log categories `(name, description)`; `fmi3SetDebugLogging` switches them.
pub const LOG_CATEGORIES: [(&str, &str); 2] = [
    ("logEvents", "instantiation, initialization, reset and termination"),
    ("logStatusError", "why a call returned fmi3Error (on unless switched off)"),
];

/// The model description with its instantiation token.
pub fn model_description(spec: &Spec) -> Result<String, String> {
    render(spec, &token(spec)?)
}

/// The instantiation token: `{8-4-4-4-12}` hex digits of the SHA-256 of the description
/// rendered with an empty token.
pub fn token(spec: &Spec) -> Result<String, String> {
    let h = hex_digest(render(spec, "")?.as_bytes());
    Ok(format!("{{{}-{}-{}-{}-{}}}", &h[0..8], &h[8..12], &h[12..16], &h[16..20], &h[20..32]))
}

/// Escape text for an XML attribute value.
fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            _ => out.push(c),
        }
    }
    out
}

/// A number as `xs:double` text: the shortest decimal that reads back to the same f64.
fn num(v: f64) -> String {
    format!("{v}")
}

fn render(spec: &Spec, token: &str) -> Result<String, String> {
    // Divided, not multiplied by 1e-6: the correctly rounded decimal (0.0001, not
    // 0.00009999999999999999).
    let dt_s = f64::from(spec.settings.dt_us) / 1e6;
    let mut x = String::new();
    let _ = write!(
        x,
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <fmiModelDescription\n  fmiVersion=\"3.0\"\n  modelName=\"simrod\"\n  \
         description=\"{}\"\n  generationTool=\"simrod-fmu {}\"\n  \
         instantiationToken=\"{}\"\n  variableNamingConvention=\"flat\">\n\n",
        esc("SimRod E-powertrain test bench twin (Kyburz DXP drive, two load motors), fixed step"),
        env!("CARGO_PKG_VERSION"),
        esc(token)
    );
    let _ = write!(
        x,
        "  <CoSimulation\n    modelIdentifier=\"{MODEL_IDENTIFIER}\"\n    \
         canHandleVariableCommunicationStepSize=\"true\"\n    fixedInternalStepSize=\"{}\"\n    \
         canGetAndSetFMUState=\"false\"\n    canSerializeFMUState=\"false\"\n    \
         hasEventMode=\"false\"/>\n\n",
        num(dt_s)
    );
    let vars = Var::all();
    units(&mut x, &vars)?;
    types(&mut x);
    x.push_str("  <LogCategories>\n");
    for (name, doc) in LOG_CATEGORIES {
        let _ = writeln!(x, "    <Category name=\"{name}\" description=\"{}\"/>", esc(doc));
    }
    x.push_str("  </LogCategories>\n\n");
    let _ = write!(x, "  <DefaultExperiment startTime=\"0\" stepSize=\"{}\"/>\n\n", num(dt_s));
    x.push_str("  <ModelVariables>\n");
    let start = Values::start(spec);
    for v in &vars {
        variable(&mut x, v, spec, &start);
    }
    x.push_str("  </ModelVariables>\n\n  <ModelStructure>\n");
    // Outputs are the last step's values: setting an input changes none of them until
    // the next step (no direct feedthrough), hence the empty dependency lists.
    for kind in ["Output", "InitialUnknown"] {
        for v in vars.iter().filter(|v| matches!(v, Var::Output(_))) {
            let _ = writeln!(x, "    <{kind} valueReference=\"{}\" dependencies=\"\"/>", v.vr());
        }
    }
    x.push_str("  </ModelStructure>\n\n</fmiModelDescription>\n");
    Ok(x)
}

fn units(x: &mut String, vars: &[Var]) -> Result<(), String> {
    let used: BTreeSet<&str> = vars.iter().map(Var::unit).filter(|u| *u != DIMENSIONLESS).collect();
    x.push_str("  <UnitDefinitions>\n");
    for u in used {
        let Some(b) = base_unit(u) else {
            let who = vars.iter().find(|v| v.unit() == u).map(Var::describe).unwrap_or_default();
            return Err(format!("unit `{u}` of {who} has no SI definition in fmu/src/units.rs"));
        };
        let _ = write!(x, "    <Unit name=\"{}\">\n      <BaseUnit", esc(u));
        for (name, e) in [("kg", b.kg), ("m", b.m), ("s", b.s), ("A", b.a), ("rad", b.rad)] {
            if e != 0 {
                let _ = write!(x, " {name}=\"{e}\"");
            }
        }
        if b.factor != 1.0 {
            let _ = write!(x, " factor=\"{}\"", num(b.factor));
        }
        x.push_str("/>\n    </Unit>\n");
    }
    x.push_str("  </UnitDefinitions>\n\n");
    Ok(())
}

fn types(x: &mut String) {
    x.push_str("  <TypeDefinitions>\n");
    for c in Choice::ALL {
        let _ =
            writeln!(x, "    <EnumerationType name=\"{}\" description=\"{}\">", c.type_name(), esc(c.doc()));
        for (k, (name, doc)) in c.items().iter().enumerate() {
            let _ =
                writeln!(x, "      <Item name=\"{name}\" value=\"{}\" description=\"{}\"/>", k + 1, esc(doc));
        }
        x.push_str("    </EnumerationType>\n");
    }
    x.push_str("  </TypeDefinitions>\n\n");
}

/// One `<Float64 .../>` or `<Enumeration .../>` element.
fn variable(x: &mut String, v: &Var, spec: &Spec, start: &Values) {
    let mut a: Vec<(&str, String)> = vec![("name", v.name()), ("valueReference", v.vr().to_string())];
    match v {
        Var::Time => {
            a.push(("description", "simulation time".into()));
            a.push(("causality", "independent".into()));
            a.push(("variability", "continuous".into()));
        }
        Var::Input(i) => {
            let (lo, hi) = if *i == Input::Supply { spec.supply_range() } else { SET_POINT_RANGE };
            a.push(("description", i.doc().into()));
            a.push(("causality", "input".into()));
            a.push(("variability", "continuous".into()));
            a.extend([("min", num(lo)), ("max", num(hi))]);
            a.push(("start", num(start.inputs[i.index()])));
        }
        Var::Choice(c) => {
            a.push(("description", c.doc().into()));
            a.push(("causality", "parameter".into()));
            a.push(("variability", "fixed".into()));
            a.push(("declaredType", c.type_name().into()));
            a.push(("start", start.choices.get(*c).to_string()));
        }
        Var::Output(_) => {
            a.push(("causality", "output".into()));
            a.push(("variability", "continuous".into()));
        }
        Var::Effect(p) => {
            let r = p.param.range;
            a.push(("description", p.param.doc.into()));
            a.push(("causality", "parameter".into()));
            a.push(("variability", "fixed".into()));
            a.extend([("min", num(f64::from(r.min))), ("max", num(f64::from(r.max)))]);
            a.push(("start", num(start.effect(spec, p))));
        }
    }
    if v.unit() != DIMENSIONLESS {
        a.push(("unit", v.unit().into()));
    }
    let _ = write!(x, "    <{}", v.ty().name());
    for (k, val) in a {
        let _ = write!(x, " {k}=\"{}\"", esc(&val));
    }
    x.push_str("/>\n");
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::Settings;
    use model_core::{Channel, Effects};

    fn spec() -> Spec {
        Spec { settings: Settings::default(), effects: Effects::NONE, data: None }
    }

    #[test]
    fn every_channel_and_effect_parameter_is_declared_with_its_unit() {
        let xml = model_description(&spec()).unwrap();
        for c in Channel::ALL {
            let line = xml.lines().find(|l| l.contains(&format!("name=\"{}\"", esc(c.name())))).unwrap();
            assert!(line.contains("causality=\"output\""), "{line}");
            if c.unit() != "-" {
                assert!(line.contains(&format!("unit=\"{}\"", c.unit())), "{line}");
            }
        }
        for p in crate::vars::effect_params() {
            let line = xml.lines().find(|l| l.contains(&format!("name=\"{}\"", p.name()))).unwrap();
            assert!(
                line.contains("variability=\"fixed\"") && line.contains("causality=\"parameter\""),
                "{line}"
            );
        }
        assert!(xml.contains("fixedInternalStepSize=\"0.001\""));
    }

    #[test]
    fn token_depends_on_what_the_fmu_runs() {
        let a = token(&spec()).unwrap();
        assert_eq!(a, token(&spec()).unwrap());
        assert_eq!(a.len(), 38);
        let mut s = spec();
        s.settings.dt_us = 100;
        assert_ne!(token(&s).unwrap(), a);
        let mut s = spec();
        s.effects.controller_delay_s = 0.012;
        assert_ne!(token(&s).unwrap(), a);
        assert!(model_description(&spec()).unwrap().contains(&format!("instantiationToken=\"{a}\"")));
    }
}
