//! The key space a bridge uses on Zenoh: everything of domain `D` under `modbot/D/`.
//!
//! ```text
//! modbot/D/M/call          query: call a method of module M (exported by D's bridge)
//! modbot/D/M/report/E/F    put: a report to module M of D, from module F of domain E
//! modbot/D/M/bb            put: the newest blackboard snapshot of module M (exported by D)
//! modbot/D/_bridge         liveliness token: D's bridge is there (the link is up)
//! ```
//! Domain and module names are `[A-Za-z0-9_-]`, which key expressions take as they are.

/// The key of a call of module `module` of domain `domain`.
pub fn call(domain: &str, module: &str) -> String {
    format!("modbot/{domain}/{module}/call")
}

/// Every call to a module of `domain`.
pub fn calls(domain: &str) -> String {
    format!("modbot/{domain}/*/call")
}

/// The key of a report to module `to` of `domain` from the module `from` of domain
/// `from_domain`.
pub fn report(domain: &str, to: &str, from_domain: &str, from: &str) -> String {
    format!("modbot/{domain}/{to}/report/{from_domain}/{from}")
}

/// Every report to a module of `domain`.
pub fn reports(domain: &str) -> String {
    format!("modbot/{domain}/*/report/*/*")
}

/// The key of the blackboard snapshots of module `module` of domain `domain`.
pub fn snapshot(domain: &str, module: &str) -> String {
    format!("modbot/{domain}/{module}/bb")
}

/// The liveliness token of `domain`'s bridge.
pub fn alive(domain: &str) -> String {
    format!("modbot/{domain}/_bridge")
}

/// The module, the sender's domain and the sender's module of a report's key `key` of
/// `domain`.
pub fn report_parts<'a>(domain: &str, key: &'a str) -> Option<(&'a str, &'a str, &'a str)> {
    let rest = key.strip_prefix("modbot/")?.strip_prefix(domain)?;
    let rest = rest.strip_prefix('/')?;
    let (to, rest) = rest.split_once('/')?;
    let (from_domain, from) = rest.strip_prefix("report/")?.split_once('/')?;
    Some((to, from_domain, from))
}

/// The module a call's key `key` of `domain` names.
pub fn call_module<'a>(domain: &str, key: &'a str) -> Option<&'a str> {
    let rest = key.strip_prefix("modbot/")?.strip_prefix(domain)?;
    rest.strip_prefix('/')?.strip_suffix("/call")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_name_the_domain_the_module_and_what_goes() {
        assert_eq!(call("robot", "high_level"), "modbot/robot/high_level/call");
        assert_eq!(
            call_module("robot", "modbot/robot/high_level/call"),
            Some("high_level")
        );
        assert_eq!(call_module("robot", "modbot/robotx/high_level/call"), None);
        let key = report("station", "control_station", "robot", "intrusion");
        assert_eq!(key, "modbot/station/control_station/report/robot/intrusion");
        assert_eq!(
            report_parts("station", &key),
            Some(("control_station", "robot", "intrusion"))
        );
        assert_eq!(alive("robot"), "modbot/robot/_bridge");
        assert_eq!(snapshot("robot", "mobility"), "modbot/robot/mobility/bb");
    }
}
