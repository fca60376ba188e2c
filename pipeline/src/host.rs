//! Which machine and process wrote a file that several machines may share (an output's
//! temporaries, a batch's claims): a process id means something only where it was taken, so
//! every such file names the place its pid belongs to.
//!
//! The place is the kernel's boot (`/proc/sys/kernel/random/boot_id`) and the PID namespace
//! (`/proc/self/ns/pid`): two containers on one kernel have their own pids, and two machines
//! may share a host name. The host name is kept for people.

use std::sync::OnceLock;

/// This process's place and name.
#[derive(Clone, Debug)]
pub struct Host {
    /// The host name, for messages.
    pub name: String,
    /// 16 hex digits: where this process's pid is meaningful (boot and PID namespace).
    pub id: String,
}

/// This process's host.
pub fn this() -> &'static Host {
    static HOST: OnceLock<Host> = OnceLock::new();
    HOST.get_or_init(|| {
        let read = |p: &str| {
            std::fs::read_to_string(p)
                .map(|s| s.trim().to_string())
                .unwrap_or_default()
        };
        let name = read("/proc/sys/kernel/hostname");
        let boot = read("/proc/sys/kernel/random/boot_id");
        let pidns = std::fs::read_link("/proc/self/ns/pid")
            .map(|l| l.to_string_lossy().into_owned())
            .unwrap_or_default();
        let id = crate::fingerprint::Fingerprint::default()
            .field(boot.as_bytes())
            .field(pidns.as_bytes())
            .field(name.as_bytes())
            .value();
        Host {
            name: if name.is_empty() { "unknown".into() } else { name },
            id: format!("{id:016x}"),
        }
    })
}

/// When process `pid` of this host started (clock ticks since boot, `/proc/PID/stat` field 22):
/// with the pid, names one process even after the pid is reused. `None` when there is no such
/// process.
pub fn process_start(pid: u32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name (field 2) is in parentheses and may hold spaces or parentheses.
    let rest = &stat[stat.rfind(')')? + 1..];
    // Field 3 is the first after it; field 22 is the 20th.
    rest.split_whitespace().nth(19)?.parse().ok()
}

/// Whether process `pid` of this host, started at `start` (see [`process_start`]), still runs.
/// A zombie has exited: it counts as gone.
pub fn alive(pid: u32, start: u64) -> bool {
    let state = std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| s.rfind(')').map(|i| s[i + 1..].trim_start().chars().next()))
        .flatten();
    process_start(pid) == Some(start) && state != Some('Z')
}

/// This process's start (see [`process_start`]).
pub fn own_start() -> u64 {
    process_start(std::process::id()).unwrap_or(0)
}

/// Seconds since the Unix epoch, as this host's clock says.
pub fn unix_now() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn this_process_is_alive_and_a_reaped_child_is_not() {
        let me = std::process::id();
        assert!(alive(me, own_start()));
        assert!(!alive(me, own_start() + 1), "another start time is another process");
        let mut child = std::process::Command::new("true").spawn().expect("spawn true");
        let (pid, start) = (child.id(), process_start(child.id()));
        child.wait().expect("wait");
        assert!(!start.is_some_and(|s| alive(pid, s)), "a reaped child counts as gone");
        assert!(this().id.len() == 16 && this().id.chars().all(|c| c.is_ascii_hexdigit()));
    }
}
