//! How the modules ended during the soak, read from the supervisor's own lines:
//! `modbot | NAME ended (WHY); restart N in D ms` and `modbot | NAME FAILED: WHY; ...`.

use modbot_bench_kit::supervised::is_supervisor_line;

/// Restarts by why the module ended, and the modules given up.
#[derive(Debug, Default, PartialEq, Eq)]
pub struct Ends {
    /// Restarts, by why the module ended ("killed by SIGKILL", "hung", ...), in the order
    /// first seen.
    pub restarts: Vec<(String, u64)>,
    /// The supervisor's lines about modules it gave up on (without its `modbot | `).
    pub failed: Vec<String>,
}

impl Ends {
    /// From the lines holding " ended (" and those holding " FAILED: " (a module's own lines
    /// among them are left out).
    pub fn from_lines(ended: &[String], failed: &[String]) -> Ends {
        let mut sut = Ends::default();
        for line in ended.iter().filter(|l| is_supervisor_line(l)) {
            let Some(why) = line
                .split_once(" ended (")
                .and_then(|(_, rest)| rest.split_once("); restart "))
                .map(|(why, _)| why)
            else {
                continue;
            };
            // "hung (3012 ms silent), killed" → "hung"
            let why = why.split(" (").next().unwrap_or(why).to_owned();
            match sut.restarts.iter_mut().find(|(w, _)| *w == why) {
                Some((_, n)) => *n += 1,
                None => sut.restarts.push((why, 1)),
            }
        }
        sut.failed = failed
            .iter()
            .filter(|l| is_supervisor_line(l))
            .map(|l| {
                l.split_once(" | ")
                    .map_or(l.trim(), |(_, r)| r.trim())
                    .to_owned()
            })
            .collect();
        sut
    }

    /// Every restart.
    pub fn total(&self) -> u64 {
        self.restarts.iter().map(|(_, n)| n).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn restarts_are_counted_by_why_the_module_ended_and_module_lines_are_left_out() {
        let ended: Vec<String> = [
            "    modbot | journal ended (killed by SIGKILL); restart 1 in 100 ms",
            "    modbot | host_bus ended (killed by SIGKILL); restart 3 in 400 ms",
            "    modbot | mobility ended (hung (3012 ms silent), killed); restart 2 in 200 ms",
            "    modbot | near_ir ended (exit 0); not restarted (its policy)",
            "  mobility | peer sonar ended (killed by SIGKILL); restart 9 in 1 ms",
        ]
        .map(String::from)
        .into();
        let failed = vec![
            "    modbot | host_ctrl_g1 FAILED: ended (killed by SIGKILL) after 5 restarts within \
             60 s; the other modules keep running"
                .to_owned(),
        ];
        let sut = Ends::from_lines(&ended, &failed);
        assert_eq!(
            sut.restarts,
            [("killed by SIGKILL".to_owned(), 2), ("hung".to_owned(), 1)]
        );
        assert_eq!(sut.total(), 3);
        assert_eq!(sut.failed.len(), 1);
        assert!(
            sut.failed[0].starts_with("host_ctrl_g1 FAILED: "),
            "{:?}",
            sut.failed
        );
    }
}
