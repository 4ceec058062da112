//! What the operating system says about memory: this process's peak resident set and the memory
//! the machine can still give without swapping (`/proc`, Linux; `None` elsewhere).

/// Peak resident set of this process (`VmHWM` in `/proc/self/status`).
pub fn peak_rss_bytes() -> Option<u64> {
    kib_field(
        &std::fs::read_to_string("/proc/self/status").ok()?,
        "VmHWM:",
    )
}

/// Memory the machine can give new allocations without swapping (`MemAvailable` in
/// `/proc/meminfo`: free memory plus the page cache and other memory it can reclaim).
pub fn available_bytes() -> Option<u64> {
    kib_field(
        &std::fs::read_to_string("/proc/meminfo").ok()?,
        "MemAvailable:",
    )
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

    #[test]
    fn reads_a_field_in_kib() {
        let meminfo =
            "MemTotal:       24576000 kB\nMemFree:         1000 kB\nMemAvailable:   20480000 kB\n";
        assert_eq!(kib_field(meminfo, "MemAvailable:"), Some(20_480_000 * 1024));
        assert_eq!(kib_field(meminfo, "MemFree:"), Some(1000 * 1024));
        assert_eq!(kib_field(meminfo, "SwapFree:"), None);
        assert_eq!(kib_field("MemAvailable: lots kB", "MemAvailable:"), None);
        if cfg!(target_os = "linux") {
            assert!(available_bytes().is_some_and(|b| b > 0));
            assert!(peak_rss_bytes().is_some_and(|b| b > 0));
        }
    }
}
