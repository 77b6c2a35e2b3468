//! Hang detection that load cannot fool. A wall-clock limit fails a healthy run on a machine
//! busy with other work (issue 23: the suite must pass beside a large build), so an app under
//! test is judged by the CPU time of its process tree instead: it is hung when the tree used no
//! CPU at all for `STALL` (a deadlock: every thread waits), or when it used more CPU time than the
//! run's budget (a livelock, or work that never ends). Neither depends on how much of the machine
//! the app gets: a run slowed down by load still makes progress, and its CPU time stays what it
//! needs.

use std::time::{Duration, Instant};

/// How long a process tree may use no CPU at all before it counts as hung. A run here never
/// waits that long on anything but itself (the mock runtime's pacing sleeps for milliseconds).
pub const STALL: Duration = Duration::from_secs(60);

/// Watches one process tree.
pub struct Watchdog {
    pid: u32,
    cpu_budget: Duration,
    stall: Duration,
    last_ticks: u64,
    last_progress: Instant,
    last_look: Option<Instant>,
}

impl Watchdog {
    /// Watches `pid` and its descendants, which may use `cpu_budget` of CPU time in all.
    pub fn new(pid: u32, cpu_budget: Duration) -> Watchdog {
        Watchdog { pid, cpu_budget, stall: STALL, last_ticks: 0, last_progress: Instant::now(), last_look: None }
    }

    /// A tree that may wait longer than `STALL` on something outside it (a download).
    pub fn with_stall(mut self, stall: Duration) -> Watchdog {
        self.stall = stall;
        self
    }

    /// Why the tree counts as hung, or None while it makes progress within its budget. Looks at
    /// /proc at most once a second; cheap to call in a polling loop.
    pub fn hung(&mut self) -> Option<String> {
        let now = Instant::now();
        if self.last_look.is_some_and(|t| now.duration_since(t) < Duration::from_secs(1)) {
            return None;
        }
        self.last_look = Some(now);
        let ticks = tree_cpu_ticks(self.pid);
        if ticks > self.last_ticks {
            self.last_ticks = ticks;
            self.last_progress = now;
        }
        let used = ticks_to_duration(ticks);
        if used > self.cpu_budget {
            return Some(format!("its process tree used {used:.1?} of CPU time, more than the run's budget of {:?} (a livelock, or work that never ends)", self.cpu_budget));
        }
        let idle = now.duration_since(self.last_progress);
        (idle >= self.stall).then(|| format!("its process tree used no CPU time for {idle:.0?} (every thread waits: a deadlock), after {used:.1?} of CPU time"))
    }

    /// CPU time the tree has used so far.
    pub fn cpu_used(&self) -> Duration {
        ticks_to_duration(self.last_ticks)
    }

    /// The same, in clock ticks (the unit of /proc/stat, for [`MachineCpu`]).
    pub fn cpu_ticks(&self) -> u64 {
        self.last_ticks
    }
}

/// The whole machine's CPU time from /proc/stat, to tell how much of it other processes took
/// while a run was measured (a frame-rate comparison means nothing on a machine another job
/// keeps busy).
#[derive(Clone, Copy, Debug)]
pub struct MachineCpu {
    busy: u64,
    total: u64,
}

impl MachineCpu {
    pub fn now() -> MachineCpu {
        let text = std::fs::read_to_string("/proc/stat").unwrap_or_default();
        let fields: Vec<u64> = text.lines().next().unwrap_or_default().split_whitespace().skip(1).filter_map(|f| f.parse().ok()).collect();
        // user nice system idle iowait irq softirq steal (guest time is already in user).
        let total: u64 = fields.iter().take(8).sum();
        let idle = fields.get(3).copied().unwrap_or(0) + fields.get(4).copied().unwrap_or(0);
        MachineCpu { busy: total.saturating_sub(idle), total }
    }

    /// The share (0..1) of the machine's CPU time since `self` that processes other than a
    /// tree which used `tree_ticks` in that time took.
    pub fn others_share_since(&self, tree_ticks: u64) -> f64 {
        let now = MachineCpu::now();
        let total = now.total.saturating_sub(self.total).max(1);
        let others = now.busy.saturating_sub(self.busy).saturating_sub(tree_ticks);
        others as f64 / total as f64
    }
}

fn ticks_to_duration(ticks: u64) -> Duration {
    // SAFETY: sysconf only reads a constant of the system.
    let per_second = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1) as u64;
    Duration::from_millis(ticks * 1000 / per_second)
}

/// (parent pid, user + system time of the process and of its reaped children) from
/// /proc/PID/stat; None when the process is gone.
fn stat(pid: u32) -> Option<(u32, u64)> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name is in parentheses and may hold spaces or parentheses: fields are counted
    // after the last ')'. Then: state, ppid, … utime (14th field), stime, cutime, cstime.
    let fields: Vec<&str> = text.rsplit_once(')')?.1.split_whitespace().collect();
    let ppid = fields.get(1)?.parse().ok()?;
    let ticks = fields.get(11..15)?.iter().map(|f| f.parse::<i64>().unwrap_or(0).max(0) as u64).sum();
    Some((ppid, ticks))
}

/// CPU ticks used by `root` and every live descendant (a descendant that ended and was waited
/// for is in its parent's children's times).
pub fn tree_cpu_ticks(root: u32) -> u64 {
    let Ok(entries) = std::fs::read_dir("/proc") else { return 0 };
    let all: Vec<(u32, u32, u64)> = entries
        .flatten()
        .filter_map(|e| e.file_name().to_str().and_then(|n| n.parse::<u32>().ok()))
        .filter_map(|pid| stat(pid).map(|(ppid, ticks)| (pid, ppid, ticks)))
        .collect();
    let mut tree = vec![root];
    let mut total = 0;
    while let Some(p) = tree.pop() {
        for &(pid, ppid, ticks) in &all {
            if pid == p {
                total += ticks;
            }
            if ppid == p && pid != p {
                tree.push(pid);
            }
        }
    }
    total
}
