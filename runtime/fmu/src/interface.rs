//! An FMU's interface as a component sees it, read from its modelDescription.xml: the inputs
//! and outputs that become ports, the parameters that become parameters, and how each travels
//! to and from the FMU (its value references and FMI type).
//!
//! | FMI 2.0 | FMI 3.0 | port or parameter type |
//! |---|---|---|
//! | Real | Float64 | f64 |
//! | Real `x[1]` … `x[n]` (one variable per element) | Float64 with one `Dimension` of n | f64[n] |
//! | Integer | Int32, Int64 | i64 |
//! | Boolean | Boolean | bool |
//!
//! Inputs and outputs of other types are refused (a port needs a type); parameters of other
//! types are left at their start values. A port is named like its variable, every character
//! other than a letter, a digit or `_` made `_` (`der(x)` → `der_x_`); parameters keep their
//! names. Ports and parameters are in the order of the variables (an array where its first
//! element is).

use std::path::Path;

use modbot_grid::component::{ParamType, ParamValue, PortType};

use super::archive;
use super::error::{FmuError, FmuErrorKind};

/// The FMI version of an FMU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Version {
    Fmi2,
    Fmi3,
}

impl Version {
    pub fn name(self) -> &'static str {
        match self {
            Version::Fmi2 => "2.0",
            Version::Fmi3 => "3.0",
        }
    }
}

/// How values travel to and from the FMU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// FMI 2 Real, FMI 3 Float64.
    Real,
    /// FMI 2 Integer, FMI 3 Int32.
    Int32,
    /// FMI 3 Int64.
    Int64,
    /// FMI 2 and 3 Boolean.
    Bool,
}

/// An input or output.
#[derive(Debug, Clone, PartialEq)]
pub struct Port {
    pub name: String,
    pub ty: PortType,
    pub kind: Kind,
    /// Its value references: one per element (FMI 2), or one for an array variable (FMI 3).
    pub refs: Vec<u32>,
}

/// A parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Param {
    pub name: String,
    pub ty: ParamType,
    pub kind: Kind,
    pub refs: Vec<u32>,
    /// Its start value (what the FMU has unless a description sets it).
    pub start: ParamValue,
}

/// What a component needs to know of an FMU.
#[derive(Debug, Clone, PartialEq)]
pub struct Interface {
    pub version: Version,
    pub model_name: String,
    /// The name of its binary (`binaries/<platform>/<model_identifier>.so`).
    pub model_identifier: String,
    /// FMI 2's guid, FMI 3's instantiation token.
    pub token: String,
    pub description: String,
    pub inputs: Vec<Port>,
    pub outputs: Vec<Port>,
    pub params: Vec<Param>,
}

impl Interface {
    /// Reads the interface of the FMU at `path` (and checks that it has a binary for this
    /// platform).
    pub fn read(path: &Path) -> Result<Interface, FmuError> {
        let failed = |kind| FmuError::new(path, kind);
        let xml = archive::model_description(path)?;
        use fmi_schema::traits::FmiModelDescription;
        let version = fmi_schema::minimal::MinModelDescription::deserialize(&xml)
            .map_err(|e| failed(FmuErrorKind::Xml(e.to_string())))?
            .fmi_version;
        let interface = match version.split('.').next() {
            Some("2") => from_fmi2(&xml),
            Some("3") => from_fmi3(&xml),
            _ => Err(FmuErrorKind::Version(version)),
        }
        .map_err(failed)?;
        archive::check_binary(path, &interface.binary_path())?;
        Ok(interface)
    }

    /// The path in the archive of its binary for this platform.
    pub fn binary_path(&self) -> String {
        let platform = match (self.version, std::env::consts::ARCH) {
            (Version::Fmi2, _) => "linux64",
            (Version::Fmi3, "aarch64") => "aarch64-linux",
            (Version::Fmi3, _) => "x86_64-linux",
        };
        format!(
            "binaries/{platform}/{}{}",
            self.model_identifier,
            std::env::consts::DLL_SUFFIX
        )
    }
}

/// A variable's role in the component.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Role {
    Input,
    Output,
    Param,
}

/// One variable (one element of an FMI 2 array), before arrays are gathered.
struct Var {
    name: String,
    role: Role,
    kind: Option<Kind>,
    vr: u32,
    /// Elements (FMI 3 arrays), 1 for a scalar.
    len: usize,
    start: Vec<ParamValue>,
}

fn from_fmi2(xml: &str) -> Result<Interface, FmuErrorKind> {
    use fmi_schema::fmi2::{Causality, Fmi2ModelDescription, ScalarVariableElement as E};
    let md: Fmi2ModelDescription =
        fmi_schema::deserialize(xml).map_err(|e| FmuErrorKind::Xml(e.to_string()))?;
    let cs = md
        .co_simulation
        .as_ref()
        .ok_or(FmuErrorKind::NoCoSimulation)?;
    let vars = md.model_variables.variables.iter().filter_map(|v| {
        let role = match v.causality {
            Causality::Input => Role::Input,
            Causality::Output => Role::Output,
            Causality::Parameter => Role::Param,
            _ => return None,
        };
        let (kind, start) = match &v.elem {
            E::Real(r) => (Some(Kind::Real), ParamValue::F64(r.start.unwrap_or(0.0))),
            E::Integer(i) => (
                Some(Kind::Int32),
                ParamValue::I64(i64::from(i.start.unwrap_or(0))),
            ),
            E::Boolean(b) => (Some(Kind::Bool), ParamValue::Bool(b.start.unwrap_or(false))),
            _ => (None, ParamValue::F64(0.0)),
        };
        Some(Var {
            name: v.name.clone(),
            role,
            kind,
            vr: v.value_reference,
            len: 1,
            start: vec![start],
        })
    });
    let (inputs, outputs, params) = gather(vars.collect())?;
    Ok(Interface {
        version: Version::Fmi2,
        model_name: md.model_name.clone(),
        model_identifier: cs.model_identifier.clone(),
        token: md.guid.clone(),
        description: md.description.clone().unwrap_or_default(),
        inputs,
        outputs,
        params,
    })
}

fn from_fmi3(xml: &str) -> Result<Interface, FmuErrorKind> {
    use fmi_schema::fmi3::{
        AbstractVariableTrait, ArrayableVariableTrait, Causality, Fmi3ModelDescription,
        InitializableVariableTrait, Variable,
    };
    let md: Fmi3ModelDescription =
        fmi_schema::deserialize(xml).map_err(|e| FmuErrorKind::Xml(e.to_string()))?;
    let cs = md
        .co_simulation
        .as_ref()
        .ok_or(FmuErrorKind::NoCoSimulation)?;
    let mut vars = Vec::new();
    for v in &md.model_variables.variables {
        let (kind, dims, start): (Option<Kind>, usize, Vec<ParamValue>) = match v {
            Variable::Float64(f) => (
                Some(Kind::Real),
                f.dimensions().len(),
                f.start()
                    .unwrap_or(&[])
                    .iter()
                    .map(|&x| ParamValue::F64(x))
                    .collect(),
            ),
            Variable::Int32(i) => (
                Some(Kind::Int32),
                i.dimensions().len(),
                i.start()
                    .unwrap_or(&[])
                    .iter()
                    .map(|&x| ParamValue::I64(i64::from(x)))
                    .collect(),
            ),
            Variable::Int64(i) => (
                Some(Kind::Int64),
                i.dimensions().len(),
                i.start()
                    .unwrap_or(&[])
                    .iter()
                    .map(|&x| ParamValue::I64(x))
                    .collect(),
            ),
            Variable::Boolean(b) => (
                Some(Kind::Bool),
                b.dimensions().len(),
                b.start()
                    .unwrap_or(&[])
                    .iter()
                    .map(|&x| ParamValue::Bool(x))
                    .collect(),
            ),
            _ => (None, 0, Vec::new()),
        };
        let abstract_var: &dyn AbstractVariableTrait = match v {
            Variable::Float64(f) => f,
            Variable::Int32(i) => i,
            Variable::Int64(i) => i,
            Variable::Boolean(b) => b,
            Variable::Float32(f) => f,
            Variable::Int8(i) => i,
            Variable::UInt8(i) => i,
            Variable::Int16(i) => i,
            Variable::UInt16(i) => i,
            Variable::UInt32(i) => i,
            Variable::UInt64(i) => i,
            Variable::String(s) => s,
            Variable::Binary(b) => b,
            Variable::Clock(c) => c,
        };
        let role = match abstract_var.causality() {
            Causality::Input => Role::Input,
            Causality::Output => Role::Output,
            Causality::Parameter => Role::Param,
            _ => continue,
        };
        let name = abstract_var.name().to_owned();
        let len = match (v, dims) {
            (_, 0) => 1,
            (Variable::Float64(f), 1) => match f.dimensions()[0].as_fixed() {
                Some(n) if n >= 1 => usize::try_from(n).unwrap_or(usize::MAX),
                _ => {
                    let why = "an array's size must be a fixed number of 1 or more".into();
                    return Err(FmuErrorKind::Variable { name, why });
                }
            },
            _ => {
                let why = "only one-dimensional Float64 arrays are supported".into();
                return Err(FmuErrorKind::Variable { name, why });
            }
        };
        vars.push(Var {
            name,
            role,
            kind,
            vr: abstract_var.value_reference(),
            len,
            start,
        });
    }
    let (inputs, outputs, params) = gather(vars)?;
    Ok(Interface {
        version: Version::Fmi3,
        model_name: md.model_name.clone(),
        model_identifier: cs.model_identifier.clone(),
        token: md.instantiation_token.clone(),
        description: md.description.clone().unwrap_or_default(),
        inputs,
        outputs,
        params,
    })
}

/// `x[3]` → (`x`, 3).
fn element(name: &str) -> Option<(&str, usize)> {
    let (base, rest) = name.split_once('[')?;
    let index: usize = rest.strip_suffix(']')?.parse().ok()?;
    (!base.is_empty() && !base.contains('[')).then_some((base, index))
}

/// A port's name for a variable's: letters, digits and `_` kept, anything else `_`.
fn port_name(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

type Gathered = (Vec<Port>, Vec<Port>, Vec<Param>);

/// The ports and parameters of `vars`: FMI 2 arrays (`x[1]` … `x[n]`, Real) become one f64[n].
fn gather(vars: Vec<Var>) -> Result<Gathered, FmuErrorKind> {
    let (mut inputs, mut outputs, mut params) = (Vec::new(), Vec::new(), Vec::new());
    let mut done = vec![false; vars.len()];
    for i in 0..vars.len() {
        if done[i] {
            continue;
        }
        let v = &vars[i];
        // The elements of an FMI 2 array, by index.
        let mut members: Vec<(usize, usize)> = match element(&v.name) {
            Some((base, _)) => (i..vars.len())
                .filter_map(|j| {
                    let (b, index) = element(&vars[j].name)?;
                    (b == base).then_some((index, j))
                })
                .collect(),
            None => vec![(1, i)],
        };
        members.sort_unstable();
        members.iter().for_each(|&(_, j)| done[j] = true);
        let name = element(&v.name)
            .map_or(v.name.as_str(), |(b, _)| b)
            .to_owned();
        let array = element(&v.name).is_some();
        let whole = members.iter().enumerate().all(|(k, &(index, j))| {
            index == k + 1 && vars[j].role == v.role && vars[j].kind == v.kind
        });
        let refuse = |why: &str| FmuErrorKind::Variable {
            name: v.name.clone(),
            why: why.to_owned(),
        };
        if array && !(whole && v.kind == Some(Kind::Real)) {
            if v.role == Role::Param {
                continue;
            }
            return Err(refuse(
                "an array must be Real elements name[1] to name[n], all inputs or all outputs",
            ));
        }
        let refs: Vec<u32> = members.iter().map(|&(_, j)| vars[j].vr).collect();
        let len = if array { members.len() } else { v.len };
        let Some(kind) = v.kind else {
            if v.role == Role::Param {
                continue;
            }
            return Err(refuse(
                "its type cannot be a port: use Real/Float64, Integer/Int32/Int64 or Boolean",
            ));
        };
        let ty = match (kind, len) {
            (Kind::Real, 1) if !array && v.len == 1 => PortType::F64,
            (Kind::Real, n) => PortType::F64s(n),
            (Kind::Int32 | Kind::Int64, _) => PortType::I64,
            (Kind::Bool, _) => PortType::Bool,
        };
        match v.role {
            Role::Input => inputs.push(Port {
                name: port_name(&name),
                ty,
                kind,
                refs,
            }),
            Role::Output => outputs.push(Port {
                name: port_name(&name),
                ty,
                kind,
                refs,
            }),
            Role::Param => {
                let starts: Vec<ParamValue> = members
                    .iter()
                    .flat_map(|&(_, j)| vars[j].start.clone())
                    .collect();
                let (ty, start) = match (ty, starts.first()) {
                    (PortType::F64s(n), _) => {
                        let xs: Vec<f64> = starts
                            .iter()
                            .map(|s| if let ParamValue::F64(x) = s { *x } else { 0.0 })
                            .chain(std::iter::repeat(0.0))
                            .take(n)
                            .collect();
                        (ParamType::F64s, ParamValue::F64s(xs))
                    }
                    (PortType::F64, first) => (
                        ParamType::F64,
                        first.cloned().unwrap_or(ParamValue::F64(0.0)),
                    ),
                    (PortType::I64, first) => {
                        (ParamType::I64, first.cloned().unwrap_or(ParamValue::I64(0)))
                    }
                    (PortType::Bool, first) => (
                        ParamType::Bool,
                        first.cloned().unwrap_or(ParamValue::Bool(false)),
                    ),
                };
                params.push(Param {
                    name,
                    ty,
                    kind,
                    refs,
                    start,
                });
            }
        }
    }
    for ports in [&inputs, &outputs] {
        for (k, p) in ports.iter().enumerate() {
            if ports[..k].iter().any(|q| q.name == p.name) {
                return Err(FmuErrorKind::Variable {
                    name: p.name.clone(),
                    why: "two variables make ports of this name".into(),
                });
            }
        }
    }
    Ok((inputs, outputs, params))
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    use super::*;

    #[test]
    fn the_fmi2_feed_forward_has_array_ports_gathered_from_its_elements() {
        let sut = Interface::read(Path::new(modbot_fmus::FF2)).unwrap();
        assert_eq!(
            (sut.version, sut.model_identifier.as_str()),
            (Version::Fmi2, "modbot_ff2")
        );
        let names = |ports: &[Port]| -> Vec<String> {
            ports
                .iter()
                .map(|p| format!("{}:{}", p.name, p.ty))
                .collect()
        };
        assert_eq!(names(&sut.inputs), ["q:f64[6]", "qd:f64[6]", "qdd:f64[6]"]);
        assert_eq!(names(&sut.outputs), ["tau:f64[6]", "qm:f64[6]"]);
        assert_eq!(sut.inputs[1].refs, [6, 7, 8, 9, 10, 11]);
        let jl = sut.params.iter().find(|p| p.name == "Jl").unwrap();
        assert_eq!(
            (jl.kind, jl.start.clone(), jl.refs.clone()),
            (Kind::Real, ParamValue::F64(2.0), vec![31])
        );
    }

    #[test]
    fn the_fmi3_filter_has_scalar_ports_and_its_parameters() {
        let sut = Interface::read(Path::new(modbot_fmus::FILTER3)).unwrap();
        assert_eq!(sut.version, Version::Fmi3);
        assert_eq!((sut.inputs.len(), sut.outputs.len()), (1, 1));
        assert_eq!(
            (sut.inputs[0].name.as_str(), sut.inputs[0].ty),
            ("u", PortType::F64)
        );
        let params: Vec<&str> = sut.params.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(params, ["k", "T"]);
    }

    /// A zip archive at a path of the test's own with `entries`.
    fn archive(tag: &str, entries: &[(&str, &[u8])]) -> std::path::PathBuf {
        let path =
            std::env::temp_dir().join(format!("modbot-fmu-{tag}-{}.fmu", std::process::id()));
        let mut zip = zip::ZipWriter::new(std::fs::File::create(&path).unwrap());
        for (name, bytes) in entries {
            zip.start_file(*name, zip::write::SimpleFileOptions::default())
                .unwrap();
            zip.write_all(bytes).unwrap();
        }
        zip.finish().unwrap();
        path
    }

    #[test]
    fn a_broken_fmu_is_refused_saying_what_is_wrong_with_it() {
        let xml = archive::model_description(Path::new(modbot_fmus::FF2)).unwrap();
        type Case<'a> = (&'a str, &'a [(&'a str, &'a [u8])], &'a str);
        let cases: [Case; 4] = [
            ("nomd", &[("x.txt", b"x")], "has no modelDescription.xml"),
            (
                "badxml",
                &[("modelDescription.xml", b"<fmiModelDescription")],
                "modelDescription.xml is not valid",
            ),
            (
                "nobin",
                &[("modelDescription.xml", xml.as_bytes())],
                "has no binary for this platform: binaries/linux64/modbot_ff2.so",
            ),
            (
                "v1",
                &[(
                    "modelDescription.xml",
                    b"<fmiModelDescription fmiVersion=\"1.0\" modelName=\"m\"/>",
                )],
                "is FMI version '1.0'",
            ),
        ];
        for (tag, entries, expected) in cases {
            let path = archive(tag, entries);
            let sut = Interface::read(&path).unwrap_err().to_string();
            assert!(
                sut.starts_with(&path.display().to_string()) && sut.contains(expected),
                "{tag}: {sut}"
            );
            let _ = std::fs::remove_file(&path);
        }
    }
}
