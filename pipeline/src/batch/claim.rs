//! Claims: a batch process claims a scene in the output folder before computing it, so shards of
//! a job array and batches started at once on one folder compute each scene once.
//!
//! A claim is the file `<output>.claim` beside the output, holding its owner (host, pid and the
//! pid's start time, shard, when it started and last renewed, its lease) as JSON.
//! - **Create**: the owner's record is written and flushed under a temporary name, then
//!   hard-linked to the claim's name. `link` fails when the name exists, atomically, on local
//!   file systems and on NFS (v2 and later), where `O_EXCL` was not always honoured; a lost reply
//!   to a `link` that succeeded is recognised by the temporary's link count of 2. A claim is never
//!   seen half-written.
//! - **Renew**: every quarter lease the owner writes a new record (its `renewed` time) under a
//!   temporary name and renames it over the claim (`rename` is atomic on NFS too), after checking
//!   the claim is still its own.
//! - **Alive or gone**: an owner on this host (same boot and PID namespace, [`crate::host`]) is
//!   alive while its pid runs with the same start time, so a killed shard restarted on its node
//!   takes its scene back at once. An owner on another host is alive until its lease has run out
//!   by this host's clock, with [`CLOCK_SKEW_S`] (or the lease, if shorter) for clocks that
//!   disagree.
//! - **Take over**: a gone owner's claim is renamed to a temporary name of the taker's (of
//!   several takers exactly one rename succeeds), checked to be the record that was judged
//!   gone (not renewed meanwhile), removed, and the scene claimed anew as above.
//! - **Release**: when the scene is done or failed, the owner removes its claim (if still its own).

use crate::host;
use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;
use std::time::Duration;

/// The lease when none is given, s: an owner on another host silent for this long is gone.
pub const DEFAULT_LEASE_S: f64 = 120.0;

/// How far the clocks of hosts sharing a folder may disagree, s (NTP keeps them within
/// milliseconds; this is for a host whose clock is not kept). A lease shorter than this
/// allows its own length instead (a short lease is for a test or one fast file system).
pub const CLOCK_SKEW_S: f64 = 30.0;

/// Shortest and longest lease accepted, s.
pub const LEASE_RANGE_S: (f64, f64) = (1.0, 86_400.0);

/// Longest claim file read (a record is a few hundred bytes).
const MAX_CLAIM_BYTES: u64 = 64 << 10;

/// Who holds a claim.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Owner {
    /// Host name.
    pub host: String,
    /// Where `pid` means something ([`crate::host::Host::id`]).
    pub host_id: String,
    /// Process id.
    pub pid: u32,
    /// The process's start (clock ticks since boot): with `pid`, one process.
    pub pid_start: u64,
    /// The shard, `K/N`, when the owner is one.
    pub shard: Option<String>,
    /// When the claim was made, s since the Unix epoch (the owner's clock).
    pub started_unix: f64,
    /// When it was last renewed, s since the Unix epoch (the owner's clock).
    pub renewed_unix: f64,
    /// The owner is gone when silent for this long, s.
    pub lease_s: f64,
    /// This claim among all the owner made.
    pub token: String,
}

impl Owner {
    /// Whether the owner is still at work, as seen from this host now.
    pub fn alive(&self) -> bool {
        if self.host_id == host::this().id {
            host::alive(self.pid, self.pid_start)
        } else {
            host::unix_now() - self.renewed_unix <= self.lease_s + CLOCK_SKEW_S.min(self.lease_s)
        }
    }

    /// In words: "node7 pid 4242 (shard 2/3), for 12 s" (what the file says, escaped for a
    /// terminal and cut short: the file may be anyone's).
    pub fn describe(&self) -> String {
        let text = |s: &str| ves_format::names::escape_for_terminal(&s.chars().take(64).collect::<String>());
        let shard = self
            .shard
            .as_ref()
            .map(|s| format!(" (shard {})", text(s)))
            .unwrap_or_default();
        let since = (host::unix_now() - self.started_unix).clamp(0.0, 1e9);
        format!("{} pid {}{shard}, for {since:.0} s", text(&self.host), self.pid)
    }

    /// Whether the record is one an owner could have written: a lease in range, times finite
    /// and not ahead of this host's clock by more than the allowance (a planted or damaged
    /// claim with a lease of 1e308 s, or renewed in the year 3000, would hold a scene forever).
    fn plausible(&self) -> bool {
        let (lo, hi) = LEASE_RANGE_S;
        let ahead = host::unix_now() + CLOCK_SKEW_S.min(self.lease_s);
        (lo..=hi).contains(&self.lease_s)
            && self.started_unix.is_finite()
            && self.renewed_unix.is_finite()
            && self.renewed_unix <= ahead
            && self.started_unix <= self.renewed_unix
            && self.host.len() <= 255
            && self.host_id.len() <= 64
            && self.token.len() <= 256
    }
}

/// The claim file of an output.
pub fn path_of(out: &Path) -> PathBuf {
    let mut name = out.as_os_str().to_os_string();
    name.push(".claim");
    PathBuf::from(name)
}

/// What is at a claim's path if it cannot be a claim (a directory, a FIFO, a device): a batch
/// could neither read nor replace it.
pub fn not_a_claim(path: &Path) -> Option<&'static str> {
    let meta = std::fs::symlink_metadata(path).ok()?;
    let t = meta.file_type();
    (!t.is_file() && !t.is_symlink()).then(|| crate::input::kind(&meta).unwrap_or("not a file"))
}

/// Who holds the claim of `out`, if anyone (alive or not).
pub fn holder(out: &Path) -> Option<Owner> {
    read(&path_of(out))
}

/// What [`acquire`] found.
pub enum Acquired {
    /// The scene is this process's to compute.
    Mine(Claim),
    /// Another process, alive, holds it.
    Held(Owner),
}

/// A claim this process holds: renewed on a thread of its own, released when dropped.
pub struct Claim {
    path: PathBuf,
    owner: std::sync::Arc<Mutex<Owner>>,
    lost: std::sync::Arc<AtomicBool>,
    stop: Option<mpsc::Sender<()>>,
    renewer: Option<std::thread::JoinHandle<()>>,
    took_over: Option<Owner>,
    /// Releases the claim if a signal ends the process.
    _on_signal: crate::workdir::SignalGuard,
}

impl Claim {
    /// The gone owner whose claim this one replaced, if any: its temporaries are known dead.
    pub fn took_over(&self) -> Option<&Owner> {
        self.took_over.as_ref()
    }

    /// Whether another process took the claim over (this one was silent past its lease).
    pub fn lost(&self) -> bool {
        self.lost.load(Ordering::Relaxed)
    }
}

impl Drop for Claim {
    fn drop(&mut self) {
        drop(self.stop.take());
        if let Some(t) = self.renewer.take() {
            let _ = t.join();
        }
        let token = self.owner.lock().unwrap_or_else(|p| p.into_inner()).token.clone();
        release(&self.path, &token);
    }
}

/// Removes the claim at `path` if it is still the one of `token`.
fn release(path: &Path, token: &str) {
    if read(path).is_some_and(|o| o.token == token) {
        let _ = std::fs::remove_file(path);
    }
}

/// Claims `out` for this process, taking over the claim of an owner that is gone.
pub fn acquire(out: &Path, lease_s: f64, shard: Option<String>) -> Result<Acquired> {
    let path = path_of(out);
    if let Some(what) = not_a_claim(&path) {
        anyhow::bail!(
            "{}: {what}, not a claim file; remove it (a batch claims a scene by creating this file)",
            path.display()
        );
    }
    // Temporaries of a claimant killed between writing and linking.
    crate::output::remove_stale_temps(&path);
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let me = host::this();
    let now = host::unix_now();
    let owner = Owner {
        host: me.name.clone(),
        host_id: me.id.clone(),
        pid: std::process::id(),
        pid_start: host::own_start(),
        shard,
        started_unix: now,
        renewed_unix: now,
        lease_s,
        token: format!(
            "{}-{}-{}-{}",
            me.id,
            std::process::id(),
            host::own_start(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ),
    };
    // A signal that ends the process releases the claim, from before it is linked into place:
    // registered after, a SIGTERM just after the link left the claim behind (seen in CI).
    let on_signal = {
        let (path, token) = (path.clone(), owner.token.clone());
        crate::workdir::at_signal(move || {
            // No claim is linked after this (see `create`), and one linked before is removed.
            *TERMINATING.lock().unwrap_or_else(|p| p.into_inner()) = true;
            release(&path, &token);
        })
    };
    // Each round either claims, finds a live owner, or removes a gone owner's claim (which
    // another process may then claim first): a few rounds settle it.
    let mut gone = None;
    for _ in 0..8 {
        if create(&path, &owner)? {
            return Ok(Acquired::Mine(start(path, owner, gone, on_signal)));
        }
        let Some(held) = read(&path) else {
            // Removed between the link and the read: try again.
            continue;
        };
        if held.alive() {
            return Ok(Acquired::Held(held));
        }
        if take_over(&path, &held)? {
            gone = Some(held);
        }
    }
    anyhow::bail!(
        "{}: could not claim it after 8 tries (other processes keep claiming and releasing it); run the batch again",
        path.display()
    )
}

/// Set by a signal's cleanup: the process is ending, no claim is to be linked any more. Held
/// while a claim is linked, so the cleanup either comes before the link (which then does not
/// happen) or after it (and removes the claim).
static TERMINATING: Mutex<bool> = Mutex::new(false);

/// Links a new claim into place: true when this process now holds it, false when a claim exists.
fn create(path: &Path, owner: &Owner) -> Result<bool> {
    let mut tmp = crate::output::temporary_beside(path).map_err(|e| {
        let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        anyhow::anyhow!(
            "{}: cannot claim the scene: cannot write in {} ({e}); choose another --out (a batch writes its claims and outputs there)",
            path.display(),
            dir.display()
        )
    })?;
    let text = serde_json::to_vec(owner)?;
    tmp.write_all(&text)
        .and_then(|()| tmp.as_file().sync_all())
        .with_context(|| format!("{}: cannot write the claim", path.display()))?;
    let terminating = TERMINATING.lock().unwrap_or_else(|p| p.into_inner());
    if *terminating {
        anyhow::bail!("{}: not claimed: the process is ending (a signal)", path.display());
    }
    match std::fs::hard_link(tmp.path(), path) {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
        Err(e) => {
            // NFS: the link may have been made and its reply lost.
            use std::os::unix::fs::MetadataExt;
            if std::fs::metadata(tmp.path()).is_ok_and(|m| m.nlink() == 2) {
                Ok(true)
            } else {
                Err(e).with_context(|| format!("{}: cannot create the claim", path.display()))
            }
        }
    }
}

/// Removes the claim of `gone`, if it is still the record judged gone (true when removed).
fn take_over(path: &Path, gone: &Owner) -> Result<bool> {
    let moved = crate::output::temporary_beside(path)
        .with_context(|| format!("{}: cannot take the claim over", path.display()))?;
    match std::fs::rename(path, moved.path()) {
        Ok(()) => {}
        // Another process took it over first.
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
        Err(e) => return Err(e).with_context(|| format!("{}: cannot take the claim over", path.display())),
    }
    let removed = match read(moved.path()) {
        Some(o) if o == *gone => {
            tracing::warn!(
                claim = %path.display(),
                "taking over the scene of {} (gone)",
                gone.describe()
            );
            // A claim temporary it may have left between writing and linking or renaming.
            crate::output::remove_temps_of(path, &gone.host_id, gone.pid);
            true
        }
        // Renewed meanwhile (or another record): its owner lives; put it back unless a new
        // claim is already there.
        _ => {
            let _ = std::fs::hard_link(moved.path(), path);
            false
        }
    };
    // Dropping `moved` removes the name it now holds.
    Ok(removed)
}

/// The owner recorded in a claim file; an unreadable or implausible one (damaged, planted, a
/// link) is treated as held by an unknown owner on another host, renewed when the file last
/// changed, with the default lease.
fn read(path: &Path) -> Option<Owner> {
    use std::os::unix::fs::OpenOptionsExt;
    let file = std::fs::File::options()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
        .open(path);
    let meta = std::fs::symlink_metadata(path).ok()?;
    let mut text = Vec::new();
    let parsed = file.ok().filter(|_| meta.is_file()).and_then(|f| {
        f.take(MAX_CLAIM_BYTES).read_to_end(&mut text).ok()?;
        serde_json::from_slice::<Owner>(&text).ok().filter(Owner::plausible)
    });
    Some(parsed.unwrap_or_else(|| {
        let changed = meta
            .modified()
            .ok()
            .and_then(|m| m.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or(0.0, |d| d.as_secs_f64());
        Owner {
            // No file name here: the record is compared after a rename (see `take_over`).
            host: "unknown (an unreadable claim file)".into(),
            host_id: String::new(),
            pid: 0,
            pid_start: 0,
            shard: None,
            started_unix: changed,
            renewed_unix: changed,
            lease_s: DEFAULT_LEASE_S,
            token: String::new(),
        }
    }))
}

/// Starts renewing a claim just made (`on_signal` releases it if a signal ends the process).
fn start(path: PathBuf, owner: Owner, took_over: Option<Owner>, on_signal: crate::workdir::SignalGuard) -> Claim {
    let every = Duration::from_secs_f64(owner.lease_s / 4.0);
    let owner = std::sync::Arc::new(Mutex::new(owner));
    let lost = std::sync::Arc::new(AtomicBool::new(false));
    let (stop, stopped) = mpsc::channel::<()>();
    let renewer = {
        let (path, owner, lost) = (path.clone(), owner.clone(), lost.clone());
        std::thread::Builder::new()
            .name("ves-claim".into())
            .spawn(move || {
                while let Err(mpsc::RecvTimeoutError::Timeout) = stopped.recv_timeout(every) {
                    if let Err(e) = renew(&path, &owner) {
                        tracing::warn!(claim = %path.display(), "{e:#}");
                        lost.store(true, Ordering::Relaxed);
                        break;
                    }
                }
            })
            .ok()
    };
    if renewer.is_none() {
        tracing::warn!(claim = %path.display(), "no thread to renew the claim: another host may take it over after its lease");
    }
    Claim {
        path,
        owner,
        lost,
        stop: Some(stop),
        renewer,
        took_over,
        _on_signal: on_signal,
    }
}

/// Writes the claim again with the time now, if it is still this process's.
fn renew(path: &Path, owner: &Mutex<Owner>) -> Result<()> {
    let mut o = owner.lock().unwrap_or_else(|p| p.into_inner());
    match read(path) {
        Some(held) if held.token == o.token => {}
        Some(held) => anyhow::bail!(
            "the claim was taken over by {} (this process was silent past its lease): both compute the scene",
            held.describe()
        ),
        None => anyhow::bail!("the claim was removed by another process: the scene may be computed twice"),
    }
    o.renewed_unix = host::unix_now();
    let text = serde_json::to_vec(&*o)?;
    crate::output::write_atomically(path, |p| Ok(std::fs::write(p, &text)?))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_claim_is_held_once_renewed_and_released() {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join("a.h5");
        let Acquired::Mine(claim) = acquire(&out, 1.0, Some("1/2".into())).expect("claim") else {
            panic!("a free scene is claimed");
        };
        let first = holder(&out).expect("the claim file");
        assert_eq!(first.pid, std::process::id());
        // Held by a live process (this one): a second claimant is told who.
        match acquire(&out, 1.0, None).expect("second") {
            Acquired::Held(o) => assert_eq!(o.token, first.token),
            Acquired::Mine(_) => panic!("claimed twice"),
        }
        // Renewed every quarter lease.
        std::thread::sleep(Duration::from_millis(700));
        let later = holder(&out).expect("the claim file");
        assert_eq!(later.token, first.token);
        assert!(later.renewed_unix > first.renewed_unix, "not renewed");
        assert!(!claim.lost());
        drop(claim);
        assert!(!path_of(&out).exists(), "released");
        let left: Vec<_> = std::fs::read_dir(dir.path()).expect("ls").collect();
        assert!(left.is_empty(), "left behind: {left:?}");
    }

    #[test]
    fn a_gone_owners_claim_is_taken_over_and_a_live_foreign_one_is_not() {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join("a.h5");
        let now = host::unix_now();
        let record = |host_id: &str, pid: u32, renewed: f64| Owner {
            host: "elsewhere".into(),
            host_id: host_id.into(),
            pid,
            pid_start: 1,
            shard: None,
            started_unix: renewed,
            renewed_unix: renewed,
            lease_s: 10.0,
            token: format!("t{pid}"),
        };
        let plant = |o: &Owner| std::fs::write(path_of(&out), serde_json::to_vec(o).expect("json")).expect("plant");
        // Another host, renewed just now: alive.
        plant(&record("00000000deadbeef", 7, now));
        assert!(matches!(acquire(&out, 5.0, None).expect("claim"), Acquired::Held(_)));
        // Another host, silent past its lease and the clock allowance: gone.
        plant(&record(
            "00000000deadbeef",
            7,
            now - 10.0 - CLOCK_SKEW_S.min(10.0) - 5.0,
        ));
        let Acquired::Mine(claim) = acquire(&out, 5.0, None).expect("claim") else {
            panic!("a lapsed lease is taken over");
        };
        assert_eq!(claim.took_over().map(|o| o.pid), Some(7));
        drop(claim);
        // This host, a pid that cannot exist: gone at once, whatever its lease says.
        plant(&record(&host::this().id, 4_999_999, now));
        assert!(matches!(acquire(&out, 5.0, None).expect("claim"), Acquired::Mine(_)));
        // A damaged claim counts as held until it has not changed for a lease.
        std::fs::write(path_of(&out), b"{not json").expect("plant");
        assert!(matches!(acquire(&out, 5.0, None).expect("claim"), Acquired::Held(_)));
        // So does an implausible one — a lease of 1e308 s, a renewal in the year 33658 — which
        // it would otherwise hold forever: once untouched for the default lease, it is taken.
        let an_hour_ago = std::time::SystemTime::now() - Duration::from_secs(3600);
        for (lease, renewed) in [(1e308, now), (10.0, 1e12), (f64::NAN, now)] {
            let mut o = record("00000000deadbeef", 7, now);
            (o.lease_s, o.renewed_unix) = (lease, renewed);
            let text = serde_json::to_string(&o).expect("json").replace("null", "1e999");
            std::fs::write(path_of(&out), text).expect("plant");
            assert!(
                matches!(acquire(&out, 5.0, None).expect("claim"), Acquired::Held(_)),
                "{lease} {renewed}"
            );
            std::fs::File::options()
                .write(true)
                .open(path_of(&out))
                .and_then(|f| f.set_modified(an_hour_ago))
                .expect("mtime");
            assert!(
                matches!(acquire(&out, 5.0, None).expect("claim"), Acquired::Mine(_)),
                "{lease} {renewed}"
            );
        }
        // A directory where the claim goes can be neither read nor replaced: said, with what to do.
        std::fs::create_dir(path_of(&out)).expect("mkdir");
        let e = acquire(&out, 5.0, None).err().expect("refused");
        assert!(
            e.to_string().contains("a directory, not a claim file; remove it"),
            "{e}"
        );
    }

    /// Sixteen threads race for one scene, twenty times: exactly one wins each time.
    #[test]
    fn racing_claimants_get_one_claim() {
        let dir = tempfile::tempdir().expect("tempdir");
        for round in 0..20 {
            let out = dir.path().join(format!("s{round}.h5"));
            let wins = AtomicU64::new(0);
            let barrier = std::sync::Barrier::new(16);
            std::thread::scope(|s| {
                let mut held = Vec::new();
                for _ in 0..16 {
                    held.push(s.spawn(|| {
                        barrier.wait();
                        let got = acquire(&out, 10.0, None).expect("claim");
                        if let Acquired::Mine(c) = got {
                            wins.fetch_add(1, Ordering::Relaxed);
                            Some(c)
                        } else {
                            None
                        }
                    }));
                }
                let claims: Vec<_> = held.into_iter().map(|h| h.join().expect("thread")).collect();
                drop(claims);
            });
            assert_eq!(wins.load(Ordering::Relaxed), 1, "round {round}");
        }
    }
}
