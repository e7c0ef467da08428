//! What a bridge exports and imports, and how it joins Zenoh: read from its command line (the
//! supervisor writes it from the description's `bridge { ... }`), checked before anything
//! opens.

use std::path::PathBuf;

use modbot_ipc_schema::{sysmethod, Addr};

/// What is wrong with a bridge's options.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    #[error("--export '{0}': expected MODULE or MODULE:METHOD,METHOD")]
    Export(String),
    #[error("--import '{0}': expected LOCAL_NAME@ADDRESS=DOMAIN/MODULE (e.g. base_mobility@40=base/mobility)")]
    Import(String),
    #[error("--import '{spec}': address {addr} is not a module address (1..=254)")]
    ImportAddr { spec: String, addr: String },
    #[error(
        "'{0}' is not a module or domain name: use 1 to 48 characters of a-z, A-Z, 0-9, _ and -"
    )]
    Name(String),
    #[error("--zenoh-mode '{0}': expected peer or client")]
    Mode(String),
    #[error("{what} '{endpoint}': a Zenoh endpoint looks like tcp/10.0.0.1:7447")]
    Endpoint {
        what: &'static str,
        endpoint: String,
    },
    #[error("Zenoh configuration {}: {why}", file.display())]
    File { file: PathBuf, why: String },
    #[error("Zenoh configuration: {0}")]
    Zenoh(String),
}

/// A module this bridge lets remote domains call.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Export {
    pub module: String,
    /// The methods remote callers may call; `None`: every method. With a list, the reading
    /// system methods (describe, stats, bb_get, bb_snapshot) are allowed too.
    pub methods: Option<Vec<String>>,
}

/// The system methods a list of exported methods allows besides its own: they read.
pub const READING: [u8; 4] = [
    sysmethod::DESCRIBE,
    sysmethod::STATS,
    sysmethod::BB_GET,
    sysmethod::BB_SNAPSHOT,
];

impl Export {
    /// Reads `MODULE` or `MODULE:METHOD,METHOD`.
    pub fn parse(spec: &str) -> Result<Export, ConfigError> {
        let (module, methods) = match spec.split_once(':') {
            None => (spec, None),
            Some((m, list)) => {
                let methods: Vec<String> = list
                    .split(',')
                    .map(str::trim)
                    .filter(|s| !s.is_empty())
                    .map(str::to_owned)
                    .collect();
                if methods.is_empty() {
                    return Err(ConfigError::Export(spec.to_owned()));
                }
                (m, Some(methods))
            }
        };
        name(module)?;
        Ok(Export {
            module: module.to_owned(),
            methods,
        })
    }

    /// Whether a remote caller may call `method`.
    pub fn allows(&self, method: &str) -> bool {
        match &self.methods {
            None => true,
            Some(list) => {
                list.iter().any(|m| m == method)
                    || sysmethod::id(method).is_some_and(|id| READING.contains(&id))
            }
        }
    }
}

/// A remote module this bridge puts into the local phone book.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Import {
    /// Its name here.
    pub local: String,
    /// Its address here.
    pub addr: Addr,
    /// The remote domain.
    pub domain: String,
    /// Its name there.
    pub module: String,
}

impl Import {
    /// Reads `LOCAL@ADDR=DOMAIN/MODULE`.
    pub fn parse(spec: &str) -> Result<Import, ConfigError> {
        let bad = || ConfigError::Import(spec.to_owned());
        let (local, remote) = spec.split_once('=').ok_or_else(bad)?;
        let (local, addr) = local.split_once('@').ok_or_else(bad)?;
        let (domain, module) = remote.split_once('/').ok_or_else(bad)?;
        let addr = addr
            .parse::<u8>()
            .ok()
            .filter(|a| (1..=254).contains(a))
            .ok_or_else(|| ConfigError::ImportAddr {
                spec: spec.to_owned(),
                addr: addr.to_owned(),
            })?;
        for n in [local, domain, module] {
            name(n)?;
        }
        Ok(Import {
            local: local.to_owned(),
            addr: Addr(addr),
            domain: domain.to_owned(),
            module: module.to_owned(),
        })
    }
}

/// Checks a module or domain name.
fn name(n: &str) -> Result<(), ConfigError> {
    if modbot_ipc_schema::names::is_module_name(n.as_bytes()) {
        Ok(())
    } else {
        Err(ConfigError::Name(n.to_owned()))
    }
}

/// How the bridge joins Zenoh.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Joining {
    /// `peer` or `client`.
    pub mode: Option<String>,
    pub listen: Vec<String>,
    pub connect: Vec<String>,
    /// A Zenoh configuration file (JSON5 or YAML); the options above override it.
    pub file: Option<PathBuf>,
    /// Zenoh's lease (ms): how long a silent link lasts before it counts as down.
    pub lease_ms: u64,
}

impl Joining {
    /// The Zenoh configuration: the file's (or Zenoh's defaults), without multicast scouting
    /// or gossip (a bridge reaches the endpoints it is given, nothing else), the lease, then
    /// the mode and endpoints given.
    pub fn zenoh(&self) -> Result<zenoh::Config, ConfigError> {
        let mut c = match &self.file {
            Some(file) => zenoh::Config::from_file(file).map_err(|e| ConfigError::File {
                file: file.clone(),
                why: e.to_string(),
            })?,
            None => {
                let mut c = zenoh::Config::default();
                set(&mut c, "scouting/multicast/enabled", "false")?;
                set(&mut c, "scouting/gossip/enabled", "false")?;
                set(
                    &mut c,
                    "transport/link/tx/lease",
                    &self.lease_ms.to_string(),
                )?;
                // Retry a listener's address until it exists (a link configured after start).
                set(&mut c, "listen/timeout_ms", "-1")?;
                set(&mut c, "listen/exit_on_failure", "false")?;
                c
            }
        };
        if let Some(mode) = &self.mode {
            if mode != "peer" && mode != "client" {
                return Err(ConfigError::Mode(mode.clone()));
            }
            set(&mut c, "mode", &format!("\"{mode}\""))?;
        }
        for (what, list, key) in [
            ("--listen", &self.listen, "listen/endpoints"),
            ("--connect", &self.connect, "connect/endpoints"),
        ] {
            if list.is_empty() {
                continue;
            }
            for e in list {
                if !e.contains('/') || e.contains('"') {
                    return Err(ConfigError::Endpoint {
                        what,
                        endpoint: e.clone(),
                    });
                }
            }
            let quoted: Vec<String> = list.iter().map(|e| format!("\"{e}\"")).collect();
            set(&mut c, key, &format!("[{}]", quoted.join(",")))?;
        }
        Ok(c)
    }
}

fn set(c: &mut zenoh::Config, key: &str, value: &str) -> Result<(), ConfigError> {
    c.insert_json5(key, value)
        .map_err(|e| ConfigError::Zenoh(format!("{key} = {value}: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_export_names_a_module_and_maybe_its_methods() {
        let all = Export::parse("mobility").unwrap();
        assert!(all.allows("forward") && all.allows("bb_set"));
        let some = Export::parse("high_level:patrol,stop").unwrap();
        assert!(some.allows("patrol") && some.allows("stop"));
        assert!(some.allows("describe") && some.allows("bb_snapshot"));
        assert!(!some.allows("bb_set") && !some.allows("secret"));
        assert!(Export::parse("high_level:").is_err());
        assert!(Export::parse("bad name").is_err());
    }

    #[test]
    fn an_import_names_its_local_name_address_and_remote_module() {
        let i = Import::parse("base_mobility@40=base/mobility").unwrap();
        assert_eq!(
            i,
            Import {
                local: "base_mobility".into(),
                addr: Addr(40),
                domain: "base".into(),
                module: "mobility".into()
            }
        );
        let e = Import::parse("x@0=base/mobility").unwrap_err();
        assert!(e.to_string().contains("address 0"), "{e}");
        let e = Import::parse("x=base/mobility").unwrap_err();
        assert!(e.to_string().contains("LOCAL_NAME@ADDRESS"), "{e}");
    }

    #[test]
    fn endpoints_and_mode_go_into_the_zenoh_configuration_and_bad_ones_are_named() {
        let j = Joining {
            mode: Some("peer".into()),
            listen: vec!["tcp/10.0.0.1:7447".into()],
            connect: vec!["tcp/10.0.0.2:7447".into()],
            file: None,
            lease_ms: 2000,
        };
        let c = j.zenoh().unwrap();
        assert_eq!(
            c.get_json("connect/endpoints").unwrap(),
            r#"["tcp/10.0.0.2:7447"]"#
        );
        let bad = Joining {
            mode: Some("router-ish".into()),
            ..j.clone()
        };
        assert!(bad
            .zenoh()
            .unwrap_err()
            .to_string()
            .contains("peer or client"));
        let bad = Joining {
            listen: vec!["10.0.0.1".into()],
            ..j
        };
        assert!(bad
            .zenoh()
            .unwrap_err()
            .to_string()
            .contains("--listen '10.0.0.1'"));
    }
}
