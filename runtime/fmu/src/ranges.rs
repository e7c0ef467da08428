//! The declared ranges of an FMU's variables: their `min` and `max`, or those of the type they
//! declare (`declaredType`: an FMI 2 `SimpleType`, an FMI 3 `Float64Type` …), read from the
//! text of modelDescription.xml (fmi-schema does not read FMI 2's). A parameter a description
//! sets outside its range is refused at check time (`component_type`).

use std::collections::HashMap;

/// A variable's declared bounds, inclusive; `None`: unbounded on that side.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Range {
    pub min: Option<f64>,
    pub max: Option<f64>,
}

impl Range {
    /// Whether `x` is within the bounds (NaN is not).
    pub fn contains(&self, x: f64) -> bool {
        self.min.is_none_or(|min| x >= min) && self.max.is_none_or(|max| x <= max)
    }

    /// Whether it bounds anything.
    pub fn is_bounded(&self) -> bool {
        self.min.is_some() || self.max.is_some()
    }

    /// `from -1000 to 1000`, `0 or more`, `at most 5`.
    pub fn text(&self) -> String {
        match (self.min, self.max) {
            (Some(min), Some(max)) => format!("from {min} to {max}"),
            (Some(min), None) => format!("{min} or more"),
            (None, Some(max)) => format!("at most {max}"),
            (None, None) => "any value".to_owned(),
        }
    }

    /// This range, where it has no bound, bounded by `other` (a declared type's).
    fn or(self, other: Range) -> Range {
        Range {
            min: self.min.or(other.min),
            max: self.max.or(other.max),
        }
    }
}

/// What an element says about a range: its `name`, `min`, `max` and `declaredType`.
#[derive(Default)]
struct Attributes {
    name: Option<String>,
    range: Range,
    declared_type: Option<String>,
}

/// The FMI 3 elements of numeric variables (their own attributes hold the range).
const FMI3_NUMBERS: [&str; 10] = [
    "Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64",
];

/// Every variable's declared range, by variable name, from modelDescription.xml (FMI 2 or 3).
/// A malformed document gives what was read before the fault (the schema reader reports it).
pub fn scan(xml: &str) -> HashMap<String, Range> {
    let mut variables: HashMap<String, (Range, Option<String>)> = HashMap::new();
    let mut types: HashMap<String, Range> = HashMap::new();
    // The open elements, and the attributes of the one being read.
    let mut open: Vec<String> = Vec::new();
    let mut tag = String::new();
    let mut attributes = Attributes::default();
    // FMI 2: the ScalarVariable or SimpleType whose child element holds the range.
    let mut holder: Option<(bool, String)> = None;
    for token in xmlparser::Tokenizer::from(xml) {
        let Ok(token) = token else { break };
        match token {
            xmlparser::Token::ElementStart { local, .. } => {
                tag = local.as_str().to_owned();
                attributes = Attributes::default();
            }
            xmlparser::Token::Attribute { local, value, .. } => {
                let number = || value.as_str().trim().parse::<f64>().ok();
                match local.as_str() {
                    "name" => attributes.name = Some(value.as_str().to_owned()),
                    "min" => attributes.range.min = number(),
                    "max" => attributes.range.max = number(),
                    "declaredType" => attributes.declared_type = Some(value.as_str().to_owned()),
                    _ => {}
                }
            }
            xmlparser::Token::ElementEnd { end, .. } => match end {
                xmlparser::ElementEnd::Open | xmlparser::ElementEnd::Empty => {
                    let parent = open.last().map(String::as_str).unwrap_or("");
                    let a = std::mem::take(&mut attributes);
                    match (tag.as_str(), parent) {
                        ("ScalarVariable", _) => holder = a.name.map(|n| (true, n)),
                        ("SimpleType", _) => holder = a.name.map(|n| (false, n)),
                        (_, "ScalarVariable" | "SimpleType") => match holder.take() {
                            Some((true, name)) => {
                                variables.insert(name, (a.range, a.declared_type));
                            }
                            Some((false, name)) => {
                                types.insert(name, a.range);
                            }
                            None => {}
                        },
                        (t, "ModelVariables") if FMI3_NUMBERS.contains(&t) => {
                            if let Some(name) = a.name {
                                variables.insert(name, (a.range, a.declared_type));
                            }
                        }
                        (t, "TypeDefinitions") if t.ends_with("Type") => {
                            if let Some(name) = a.name {
                                types.insert(name, a.range);
                            }
                        }
                        _ => {}
                    }
                    if end == xmlparser::ElementEnd::Open {
                        open.push(std::mem::take(&mut tag));
                    }
                }
                xmlparser::ElementEnd::Close(..) => {
                    open.pop();
                }
            },
            _ => {}
        }
    }
    variables
        .into_iter()
        .map(|(name, (range, declared))| {
            let of_type = declared
                .and_then(|t| types.get(&t).copied())
                .unwrap_or_default();
            (name, range.or(of_type))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_variables_range_is_its_own_or_its_declared_types_in_either_version() {
        let fmi2 = r#"<fmiModelDescription fmiVersion="2.0"><TypeDefinitions>
            <SimpleType name="Angle"><Real unit="rad" min="-3.5" max="3.5"/></SimpleType>
            </TypeDefinitions><ModelVariables>
            <ScalarVariable name="n" valueReference="0"><Integer start="3" min="-10" max="10"/></ScalarVariable>
            <ScalarVariable name="q" valueReference="1"><Real declaredType="Angle" max="1"/></ScalarVariable>
            <ScalarVariable name="free" valueReference="2"><Real/></ScalarVariable>
            </ModelVariables></fmiModelDescription>"#;
        let sut = scan(fmi2);
        let range = |min, max| Range { min, max };
        assert_eq!(sut["n"], range(Some(-10.0), Some(10.0)));
        assert_eq!(sut["q"], range(Some(-3.5), Some(1.0)), "its own max first");
        assert_eq!(sut["free"], Range::default());
        let fmi3 = r#"<fmiModelDescription fmiVersion="3.0"><TypeDefinitions>
            <Float64Type name="Gain" min="0"/></TypeDefinitions><ModelVariables>
            <UInt64 name="nx" valueReference="1" start="2" min="1" max="8"/>
            <Float64 name="k" valueReference="2" declaredType="Gain"><Dimension start="2"/></Float64>
            </ModelVariables></fmiModelDescription>"#;
        let sut = scan(fmi3);
        assert_eq!(sut["nx"], range(Some(1.0), Some(8.0)));
        assert_eq!(sut["k"], range(Some(0.0), None));
        assert!(!sut["k"].contains(-1.0) && sut["k"].contains(0.0));
        assert_eq!(sut["nx"].text(), "from 1 to 8");
    }
}
