//! The machine a report ran on ([`Machine`]) and what else ran while it timed the
//! relightings ([`TimingLoad`], Linux: from `/proc`).

use serde::Serialize;

/// The machine the report ran on.
#[derive(Clone, Debug, Serialize)]
pub struct Machine {
    /// Logical cores available.
    pub cores: usize,
    /// CPU model name (from /proc/cpuinfo), if known.
    pub cpu: String,
    /// What else ran while the report relit and timed every order (Linux: from `/proc`).
    pub timing_load: Option<TimingLoad>,
}

/// The machine's load while the report was timing: how much of the CPU time went to other
/// processes (and, on a virtual machine, was stolen by the host). Timings taken while others
/// used the cores are noisy; the report says so.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct TimingLoad {
    /// Wall-clock seconds of the timed section.
    pub seconds: f64,
    /// Fraction of all cores' time used by other processes.
    pub other_cpu_fraction: f64,
    /// Fraction of all cores' time stolen by the hypervisor.
    pub steal_fraction: f64,
    /// 1-minute load average at the start and the end (all processes, this one included).
    pub load_average: [f64; 2],
}

/// Counters of `/proc/stat` (all cores) and `/proc/self/stat` at one instant, in clock ticks.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CpuSnapshot {
    at: std::time::Instant,
    total: u64,
    busy: u64,
    steal: u64,
    own: u64,
    load: f64,
}

/// The counters now (`None` where `/proc` cannot be read).
pub(crate) fn cpu_snapshot() -> Option<CpuSnapshot> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    let cpu: Vec<u64> = stat
        .lines()
        .next()?
        .split_whitespace()
        .skip(1)
        .take(8)
        .map(|v| v.parse().unwrap_or(0))
        .collect();
    if cpu.len() < 8 {
        return None;
    }
    // user nice system idle iowait irq softirq steal
    let busy = cpu[0] + cpu[1] + cpu[2] + cpu[5] + cpu[6] + cpu[7];
    let me = std::fs::read_to_string("/proc/self/stat").ok()?;
    let after = me.rsplit_once(')')?.1;
    let fields: Vec<u64> = after
        .split_whitespace()
        .map(|v| v.parse().unwrap_or(0))
        .collect();
    // Fields 14 and 15 of /proc/[pid]/stat (utime, stime) are 11 and 12 after the name.
    let own = fields.get(11)? + fields.get(12)?;
    let load = std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|l| l.split_whitespace().next()?.parse().ok())
        .unwrap_or(0.0);
    Some(CpuSnapshot {
        at: std::time::Instant::now(),
        total: cpu.iter().sum(),
        busy,
        steal: cpu[7],
        own,
        load,
    })
}

impl TimingLoad {
    /// The load between two snapshots, `a` taken first.
    pub(crate) fn between(a: CpuSnapshot, b: CpuSnapshot) -> Self {
        let total = b.total.saturating_sub(a.total).max(1) as f64;
        let busy = b.busy.saturating_sub(a.busy);
        let own = b.own.saturating_sub(a.own);
        TimingLoad {
            seconds: (b.at - a.at).as_secs_f64(),
            other_cpu_fraction: busy.saturating_sub(own) as f64 / total,
            steal_fraction: b.steal.saturating_sub(a.steal) as f64 / total,
            load_average: [a.load, b.load],
        }
    }

    /// Other processes (or the hypervisor) took more than 5 % of the cores' time.
    #[must_use]
    pub fn noisy(&self) -> bool {
        self.other_cpu_fraction > 0.05 || self.steal_fraction > 0.05
    }

    /// One sentence for the report.
    #[must_use]
    pub fn sentence(&self, cores: usize) -> String {
        format!(
            "Machine load while timing ({:.0} s): other processes used {:.1} % of the {cores} cores' time and the hypervisor stole {:.1} % (1-minute load average {:.2} → {:.2}); {}",
            self.seconds,
            100.0 * self.other_cpu_fraction,
            100.0 * self.steal_fraction,
            self.load_average[0],
            self.load_average[1],
            if self.noisy() {
                "the timings are noisy: rerun on a quiet machine before comparing them"
            } else {
                "the machine was quiet"
            }
        )
    }
}

/// The machine this runs on (no timing load yet).
pub(crate) fn machine() -> Machine {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown".into());
    Machine {
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        cpu,
        timing_load: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn snapshot(
        at: std::time::Instant,
        total: u64,
        busy: u64,
        steal: u64,
        own: u64,
    ) -> CpuSnapshot {
        CpuSnapshot {
            at,
            total,
            busy,
            steal,
            own,
            load: 0.5,
        }
    }

    #[test]
    fn the_load_between_two_snapshots_is_the_others_share_of_the_ticks() {
        let t0 = std::time::Instant::now();
        let t1 = t0 + std::time::Duration::from_secs(2);
        // 1000 ticks pass: 400 busy, of which 300 ours and 20 stolen.
        let load = TimingLoad::between(
            snapshot(t0, 5000, 2000, 10, 700),
            snapshot(t1, 6000, 2400, 30, 1000),
        );
        assert_eq!(load.seconds, 2.0);
        assert_eq!(load.other_cpu_fraction, 0.1);
        assert_eq!(load.steal_fraction, 0.02);
        assert!(load.noisy());
        assert!(load.sentence(2).contains("the timings are noisy"));
        // Only our own work: quiet.
        let quiet = TimingLoad::between(
            snapshot(t0, 5000, 2000, 10, 700),
            snapshot(t1, 6000, 2300, 10, 1000),
        );
        assert_eq!(quiet.other_cpu_fraction, 0.0);
        assert!(!quiet.noisy());
        assert!(quiet.sentence(2).ends_with("the machine was quiet"));
    }
}
