//! What the operating system says about memory: this process's peak resident set and the memory
//! it can still be given without swapping or being killed (`/proc` and the cgroup file system,
//! Linux; `None` elsewhere).

use std::path::Path;

/// Peak resident set of this process (`VmHWM` in `/proc/self/status`).
pub fn peak_rss_bytes() -> Option<u64> {
    kib_field(
        &std::fs::read_to_string("/proc/self/status").ok()?,
        "VmHWM:",
    )
}

/// Memory this process can still be given, and what sets it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Available {
    /// Bytes that new allocations can take.
    pub bytes: u64,
    /// True when a memory limit of the process's control group (a batch job's or a container's)
    /// leaves less than the machine has available.
    pub by_limit: bool,
}

pub use amr_format::output::describe_bytes;

impl Available {
    /// `available`, when `needed` bytes with a tenth to spare do not fit in it (`None` when
    /// they fit or nothing is known).
    pub fn short_of(needed: u64, available: Option<Available>) -> Option<Available> {
        available.filter(|free| needed.saturating_add(needed / 10) > free.bytes)
    }

    /// How a message names what leaves these bytes, before the amount.
    pub fn whose(&self) -> &'static str {
        if self.by_limit {
            "this process's memory limit (its control group's: a batch job's or a container's) \
             leaves"
        } else {
            "this machine has"
        }
    }
}

/// Memory this process can still be given: the machine's `MemAvailable` (`/proc/meminfo`: free
/// memory plus the page cache and other memory the kernel can reclaim), or less when the control
/// group the process runs in (a batch scheduler's job, a container) has a memory limit that
/// leaves less: the limit less the group's memory in use that the kernel cannot reclaim (its
/// page cache, such as a mapped data file's pages, is reclaimable and not counted).
pub fn available() -> Option<Available> {
    let machine = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| kib_field(&text, "MemAvailable:"));
    let group = std::fs::read_to_string("/proc/self/cgroup")
        .ok()
        .and_then(|text| cgroup_headroom(&text, Path::new("/sys/fs/cgroup")));
    let (bytes, by_limit) = match (machine, group) {
        (Some(m), Some(g)) => (m.min(g), g < m),
        (Some(m), None) => (m, false),
        (None, Some(g)) => (g, true),
        (None, None) => return None,
    };
    Some(Available { bytes, by_limit })
}

/// What the memory limits of the process's control groups leave it, the smallest over the
/// groups from its own up to the root of the hierarchy; `None` when no limit is set or none
/// can be read. `proc_cgroup` is the text of `/proc/self/cgroup`; `root` is where the cgroup
/// file system is mounted. Version 2 (one unified hierarchy, the line `0::PATH`): `memory.max`,
/// `memory.current` and `file` of `memory.stat` in each group. Version 1 (a `memory` controller
/// hierarchy under `root/memory`): `memory.limit_in_bytes`, `memory.usage_in_bytes` and
/// `total_cache` of `memory.stat`. A group's own path may not exist inside a container that
/// sees only its own group at the mount's root: that root is read then.
fn cgroup_headroom(proc_cgroup: &str, root: &Path) -> Option<u64> {
    proc_cgroup
        .lines()
        .filter_map(|line| {
            let mut parts = line.splitn(3, ':');
            let (_, controllers, path) = (parts.next()?, parts.next()?, parts.next()?);
            if controllers.is_empty() {
                smallest_up_from(root, path, &V2)
            } else if controllers.split(',').any(|c| c == "memory") {
                smallest_up_from(&root.join("memory"), path, &V1)
            } else {
                None
            }
        })
        .min()
}

/// The files of a cgroup version's memory controller that [`group_headroom`] reads.
struct MemoryFiles {
    /// The limit: a number, or a word or huge number for none.
    limit: &'static str,
    /// The memory in use.
    usage: &'static str,
    /// The `memory.stat` key of the page cache within it.
    cache: &'static str,
}

/// Version 2 (no limit: `max`).
const V2: MemoryFiles = MemoryFiles {
    limit: "memory.max",
    usage: "memory.current",
    cache: "file",
};

/// Version 1 (no limit: a number near `i64::MAX`).
const V1: MemoryFiles = MemoryFiles {
    limit: "memory.limit_in_bytes",
    usage: "memory.usage_in_bytes",
    cache: "total_cache",
};

/// The smallest [`group_headroom`] of the groups from `path` (relative to the hierarchy's
/// `mount`) up to the mount itself; from the mount alone when `path` is not there.
fn smallest_up_from(mount: &Path, path: &str, files: &MemoryFiles) -> Option<u64> {
    let own = mount.join(path.trim_start_matches('/'));
    let start = if own.is_dir() { own.as_path() } else { mount };
    start
        .ancestors()
        .take_while(|dir| dir.starts_with(mount))
        .filter_map(|dir| group_headroom(dir, files))
        .min()
}

/// A group's limit less its memory in use other than page cache; `None` without a limit.
fn group_headroom(dir: &Path, files: &MemoryFiles) -> Option<u64> {
    let limit = read_number(&dir.join(files.limit))?;
    if limit >= 1 << 62 {
        return None;
    }
    let usage = read_number(&dir.join(files.usage))?;
    let cache = stat_field(&dir.join("memory.stat"), files.cache).unwrap_or(0);
    Some(limit.saturating_sub(usage.saturating_sub(cache)))
}

/// The number a file holds alone.
fn read_number(path: &Path) -> Option<u64> {
    std::fs::read_to_string(path).ok()?.trim().parse().ok()
}

/// The value of the line `key N` of a cgroup `memory.stat` file.
fn stat_field(path: &Path, key: &str) -> Option<u64> {
    let text = std::fs::read_to_string(path).ok()?;
    text.lines().find_map(|l| {
        let (k, v) = l.split_once(' ')?;
        (k == key).then(|| v.trim().parse().ok()).flatten()
    })
}

/// The value of the first line `key  N kB` of a `/proc` file's text, in bytes.
pub(crate) fn kib_field(text: &str, key: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(key))?;
    let kib: u64 = line[key.len()..]
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    kib.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Writes `files` (path relative to `root`, text) under `root`.
    fn write_all(root: &Path, files: &[(&str, &str)]) {
        for (path, text) in files {
            let path = root.join(path);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, text).unwrap();
        }
    }

    /// Version 2: the tightest group on the way up binds, and page cache is not counted as used.
    #[test]
    fn a_cgroup_v2_limit_up_the_tree_binds_less_its_page_cache() {
        let dir = tempfile::tempdir().unwrap();
        let gib = 1u64 << 30;
        write_all(
            dir.path(),
            &[
                // The job's group: 8 GiB, 5 GiB in use of which 4 GiB page cache: 7 GiB left.
                ("job/memory.max", &format!("{}\n", 8 * gib)),
                ("job/memory.current", &format!("{}\n", 5 * gib)),
                ("job/memory.stat", &format!("anon 1024\nfile {}\n", 4 * gib)),
                // The step's group inside it: no limit of its own.
                ("job/step/memory.max", "max\n"),
                ("job/step/memory.current", "1000\n"),
            ],
        );
        let left = cgroup_headroom("0::/job/step\n", dir.path());
        assert_eq!(left, Some(7 * gib));
        // The same groups without a limit anywhere: none.
        std::fs::write(dir.path().join("job/memory.max"), "max\n").unwrap();
        assert_eq!(cgroup_headroom("0::/job/step\n", dir.path()), None);
    }

    /// Version 1: the memory controller's hierarchy; "no limit" is a huge number; a path that
    /// is not there (a container seeing only its own group) reads the mount's root.
    #[test]
    fn a_cgroup_v1_limit_binds_and_no_limit_is_none() {
        let dir = tempfile::tempdir().unwrap();
        let mib = 1u64 << 20;
        write_all(
            dir.path(),
            &[
                ("memory/memory.limit_in_bytes", "9223372036854771712\n"),
                (
                    "memory/slurm/job1/memory.limit_in_bytes",
                    &format!("{}", 512 * mib),
                ),
                (
                    "memory/slurm/job1/memory.usage_in_bytes",
                    &format!("{}", 300 * mib),
                ),
                (
                    "memory/slurm/job1/memory.stat",
                    &format!("cache 1\nrss 2\ntotal_cache {}\n", 100 * mib),
                ),
            ],
        );
        let text = "9:pids:/slurm/job1\n4:cpu,memory:/slurm/job1\n0::/\n";
        assert_eq!(cgroup_headroom(text, dir.path()), Some(312 * mib));
        assert_eq!(cgroup_headroom("4:memory:/\n", dir.path()), None);
        let container = "4:memory:/docker/abc\n";
        std::fs::write(
            dir.path().join("memory/memory.limit_in_bytes"),
            format!("{}", 64 * mib),
        )
        .unwrap();
        std::fs::write(dir.path().join("memory/memory.usage_in_bytes"), "0").unwrap();
        assert_eq!(cgroup_headroom(container, dir.path()), Some(64 * mib));
        assert_eq!(cgroup_headroom("garbage\n\n", dir.path()), None);
    }

    #[test]
    fn bytes_are_described_in_mib_below_a_gib() {
        assert_eq!(describe_bytes(87_417_888), "83 MiB");
        assert_eq!(describe_bytes(3 << 30), "3.0 GiB");
        assert_eq!(describe_bytes((1 << 30) - 1), "1024 MiB");
    }

    #[test]
    fn reads_a_field_in_kib() {
        let meminfo =
            "MemTotal:       24576000 kB\nMemFree:         1000 kB\nMemAvailable:   20480000 kB\n";
        assert_eq!(kib_field(meminfo, "MemAvailable:"), Some(20_480_000 * 1024));
        assert_eq!(kib_field(meminfo, "MemFree:"), Some(1000 * 1024));
        assert_eq!(kib_field(meminfo, "SwapFree:"), None);
        assert_eq!(kib_field("MemAvailable: lots kB", "MemAvailable:"), None);
        if cfg!(target_os = "linux") {
            assert!(available().is_some_and(|a| a.bytes > 0));
            assert!(peak_rss_bytes().is_some_and(|b| b > 0));
        }
    }
}
