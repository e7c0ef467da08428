//! When and where a run was made: the UTC date and a one-line description of the machine.

use std::time::{SystemTime, UNIX_EPOCH};

/// Today's date in UTC, `YYYY-MM-DD`.
pub fn today_utc() -> String {
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let (y, m, d) = civil_from_days((secs / 86_400) as i64);
    format!("{y:04}-{m:02}-{d:02}")
}

/// The calendar date of a day count since 1970-01-01 (Howard Hinnant's `civil_from_days`).
fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

/// "Intel(R) Xeon(R) Processor, 2 cores, 23.5 GiB RAM, Linux 6.18.44, VM (hypervisor flag)".
pub fn describe() -> String {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let meminfo = std::fs::read_to_string("/proc/meminfo").unwrap_or_default();
    let kernel = std::fs::read_to_string("/proc/sys/kernel/osrelease").unwrap_or_default();
    describe_from(&cpuinfo, &meminfo, kernel.trim(), crate::procs::cores())
}

fn describe_from(cpuinfo: &str, meminfo: &str, kernel: &str, cores: usize) -> String {
    let field = |text: &str, key: &str| {
        text.lines()
            .find(|l| l.split(':').next().is_some_and(|k| k.trim() == key))
            .and_then(|l| l.split_once(':'))
            .map(|(_, v)| v.trim().to_owned())
    };
    let mut parts = vec![
        field(cpuinfo, "model name").unwrap_or_else(|| "unknown CPU".to_owned()),
        format!("{cores} cores"),
    ];
    if let Some(kb) = field(meminfo, "MemTotal").and_then(|v| {
        v.split_whitespace()
            .next()
            .and_then(|n| n.parse::<u64>().ok())
    }) {
        parts.push(format!("{:.1} GiB RAM", kb as f64 / (1 << 20) as f64));
    }
    if !kernel.is_empty() {
        parts.push(format!("Linux {kernel}"));
    }
    let vm =
        field(cpuinfo, "flags").is_some_and(|f| f.split_whitespace().any(|x| x == "hypervisor"));
    if vm {
        parts.push("VM (hypervisor flag)".to_owned());
    }
    parts.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn day_counts_become_calendar_dates() {
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        assert_eq!(civil_from_days(19_723), (2024, 1, 1));
        assert_eq!(civil_from_days(20_513), (2026, 3, 1));
    }

    #[test]
    fn the_machine_line_names_cpu_cores_memory_kernel_and_vm() {
        let cpu = "processor\t: 0\nmodel name\t: Intel(R) Xeon(R) Processor\nflags\t\t: fpu hypervisor sse\n";
        let mem = "MemTotal:       24684092 kB\n";
        assert_eq!(
            describe_from(cpu, mem, "6.18.44", 2),
            "Intel(R) Xeon(R) Processor, 2 cores, 23.5 GiB RAM, Linux 6.18.44, VM (hypervisor flag)"
        );
        assert_eq!(describe_from("", "", "", 1), "unknown CPU, 1 cores");
    }
}
