//! The soak's system: MOSER and the arm in one domain, and the journal module the soak's calls
//! go to.
//!
//! A description cannot include another (the sandbox has no `dofile` or `require`), so the
//! benchmark writes one: a head of its own, then the text of `examples/moser.lua` and of
//! `examples/arm.lua` as they are, each in a Lua block where a few declaration functions are
//! shadowed by locals: the domain and supervision each example declares give way to the
//! soak's (one of each is allowed), MOSER's modules get the soak's restart policy (they are
//! killed over and over: they must come back every time, and none may stop the system), and
//! the arm's grid finds its assemblies where the example keeps them (a relative directory
//! would be looked for next to the written file).

use std::path::{Path, PathBuf};

use anyhow::Context;

/// The module the soak's calls go to: `modbot-faulty --journal PATH`.
pub const JOURNAL: &str = "journal";
/// Its address (MOSER has 2 to 20; the grid's processes take theirs from 253 down).
const JOURNAL_ADDR: u8 = 30;

/// Every module's restart policy: back after 0.1 s (at most 1 s when it keeps failing), never
/// given up. The grid's host processes have the supervisor's own policy for them (on failure,
/// at most 5 restarts within 60 s), which a description cannot change.
const RESTART: &str = "{ policy = \"on-failure\", max_restarts = 1000000, window = 60, \
                       backoff = 0.1, max_backoff = 1, give_up = \"keep-others\" }";

/// The supervision of the soak: MOSER's, with a heartbeat timeout longer than the 2 s stall the
/// soak injects, so that a stalled module resumes rather than being judged hung (the arm's own
/// timeout is 2 s, MOSER's 1 s).
const SUPERVISION: &str = "supervision { start_timeout = 20, heartbeat_timeout = 3.0, \
                           heartbeat_period = 0.1, stop_grace = 3 }";

/// The examples the soak runs, read from this checkout.
#[derive(Debug, Clone)]
pub struct Examples {
    pub moser: String,
    pub arm: String,
    /// The arm's assembly directory, absolute.
    pub assemblies: PathBuf,
}

impl Examples {
    /// `examples/moser.lua`, `examples/arm.lua` and `examples/arm/` of this checkout.
    pub fn read() -> anyhow::Result<Examples> {
        let arm = modbot_bench_kit::arm_system::arm_description()?;
        let dir = arm
            .parent()
            .with_context(|| format!("{} has no directory", arm.display()))?;
        let read = |p: &Path| {
            std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))
        };
        Ok(Examples {
            moser: read(&dir.join("moser.lua"))?,
            arm: read(&arm)?,
            assemblies: dir.join("arm"),
        })
    }
}

/// The soak's description: `examples` in one domain (`vars.domain`) with the journal module
/// appending to `journal`. MOSER patrols without end when `vars.endless` is given.
pub fn compose(examples: &Examples, journal: &Path) -> String {
    format!(
        r#"-- modbot-benches soak: examples/moser.lua and examples/arm.lua in one domain, and the
-- journal module the soak's calls go to. Written by the benchmark: each example's text follows
-- as it is, in a block where the declarations the soak owns are shadowed.
domain(vars.domain)
{SUPERVISION}

local soak_restart = {RESTART}
local declare_module, declare_grid = module, grid
local function ignored() end
local function restarting(name)
  return function(t)
    t.restart = soak_restart
    return declare_module(name)(t)
  end
end

module "{JOURNAL}" {{
  addr = {JOURNAL_ADDR}, program = "modbot-faulty", args = {{ "--journal", {journal} }},
  restart = soak_restart,
}}

do -- examples/moser.lua
local domain, supervision, module = ignored, ignored, restarting
{moser}
end

do -- examples/arm.lua
local domain, supervision = ignored, ignored
local function grid(t)
  t.assemblies = {assemblies}
  return declare_grid(t)
end
{arm}
end
"#,
        journal = lua_string(&journal.display().to_string()),
        moser = examples.moser.trim_end(),
        assemblies = lua_string(&examples.assemblies.display().to_string()),
        arm = examples.arm.trim_end(),
    )
}

/// `text` as a Lua string literal.
fn lua_string(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 2);
    out.push('"');
    for c in text.chars() {
        match c {
            '"' | '\\' => {
                out.push('\\');
                out.push(c);
            }
            '\n' => out.push_str("\\n"),
            c if c.is_control() => out.push_str(&format!("\\u{{{:x}}}", u32::from(c))),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use modbot_system::{self as system, Restart};

    fn load(text: &str) -> system::SystemSpec {
        let vars = [
            ("domain".to_owned(), "soak_test".to_owned()),
            ("endless".to_owned(), "1".to_owned()),
        ];
        let resolver = |name: &str| Some(PathBuf::from(name));
        system::load_str_with_vars("soak.lua", text, &resolver, &vars)
            .unwrap_or_else(|e| panic!("{e}\n{text}"))
    }

    #[test]
    fn the_examples_compose_into_one_domain_with_the_journal_and_the_arms_grid() {
        let examples = Examples::read().unwrap();
        let sut = load(&compose(&examples, Path::new("/tmp/soak \"journal\"")));
        assert_eq!(sut.domain, "soak_test");
        let names: Vec<&str> = sut.modules.iter().map(|m| m.name.as_str()).collect();
        for name in ["journal", "mobility", "high_level", "control_station"] {
            assert!(names.contains(&name), "{names:?}");
        }
        let journal = &sut.modules[0];
        assert_eq!(journal.args, ["--journal", "/tmp/soak \"journal\""]);
        let grid = sut.grid.as_ref().expect("the arm's grid");
        let assembly = grid.assembly.as_ref().expect("the arm's assemblies");
        assert_eq!(assembly.source.as_ref().unwrap().dir, examples.assemblies);
        assert_eq!(sut.supervision.heartbeat_timeout.as_secs_f64(), 3.0);
    }

    #[test]
    fn every_module_comes_back_and_moser_patrols_without_end() {
        let sut = load(&compose(&Examples::read().unwrap(), Path::new("/tmp/j")));
        for m in &sut.modules {
            assert_eq!(m.restart.when, Restart::OnFailure, "{}", m.name);
            assert!(m.restart.max_restarts >= 1_000_000, "{}", m.name);
        }
        let station = sut
            .modules
            .iter()
            .find(|m| m.name == "control_station")
            .unwrap();
        assert!(
            station
                .args
                .windows(2)
                .any(|w| w == ["--end-after-alert", "inf"]),
            "{:?}",
            station.args
        );
    }

    #[test]
    fn lua_strings_escape_quotes_backslashes_and_control_characters() {
        assert_eq!(lua_string(r#"a"b\c"#), r#""a\"b\\c""#);
        assert_eq!(lua_string("x\ny\u{1}"), r#""x\ny\u{1}""#);
    }
}
