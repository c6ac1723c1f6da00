//! What a benchmark reports besides wall time: how many cores the process kept busy and its
//! peak resident memory, both read from Linux's `/proc/self` (no crate exposes them portably;
//! elsewhere they are `None`).

use std::time::Instant;

/// Clock ticks per second of `/proc/self/stat` times: `USER_HZ`, 100 on every Linux
/// architecture rtr builds for (the kernel fixes it for user space).
const USER_HZ: f64 = 100.0;

/// CPU seconds (user + system) this process has used so far.
fn cpu_seconds() -> Option<f64> {
    let stat = crate::io::read_process_file("stat")?;
    // The command name (field 2) is in parentheses and may hold spaces: count from its end.
    let after = &stat[stat.rfind(')')? + 1..];
    let fields: Vec<&str> = after.split_whitespace().collect();
    // Fields 14 and 15 of the line (utime, stime) are the 12th and 13th after the name.
    let user: f64 = fields.get(11)?.parse().ok()?;
    let system: f64 = fields.get(12)?.parse().ok()?;
    Some((user + system) / USER_HZ)
}

/// Resident-set high-water mark of this process (MiB), from `/proc/self/status`.
pub fn peak_rss_mb() -> Option<f64> {
    let status = crate::io::read_process_file("status")?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// Resets the high-water mark to the current resident size (Linux >= 4.0).
pub fn reset_peak_rss() {
    crate::io::write_process_file("clear_refs", "5");
}

/// Measures the cores a stretch of work kept busy: CPU time over wall time since `start`.
pub struct CoreMeter {
    wall: Instant,
    cpu: Option<f64>,
}

impl CoreMeter {
    pub fn start() -> Self {
        Self {
            wall: Instant::now(),
            cpu: cpu_seconds(),
        }
    }

    /// Cores busy on average since [`Self::start`] (1.0 = one core all the time).
    pub fn cores_busy(&self) -> Option<f64> {
        let wall = self.wall.elapsed().as_secs_f64();
        let cpu = cpu_seconds()? - self.cpu?;
        (wall > 0.0).then(|| cpu / wall)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[cfg(target_os = "linux")]
    fn a_busy_loop_keeps_about_one_core_busy() {
        let meter = CoreMeter::start();
        let until = Instant::now() + std::time::Duration::from_millis(300);
        let mut x = 0u64;
        while Instant::now() < until {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
        }
        std::hint::black_box(x);
        let busy = meter.cores_busy().expect("linux has /proc");
        // One spinning thread: other test threads may add to the process's time, and other
        // processes on a loaded machine may take most of a core from it, so the bounds say only
        // that the time was counted (not 0) in cores (not in ticks or ms).
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
        assert!(
            busy > 0.1 && busy <= cores + 0.5,
            "{busy} cores busy of {cores}"
        );
        assert!(peak_rss_mb().expect("linux") > 0.0);
    }
}
