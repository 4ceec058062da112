//! Peak resident memory of this process, as the operating system keeps it (`VmHWM` in
//! `/proc/self/status`, Linux; absent elsewhere).

/// Peak resident set of this process in bytes.
pub fn peak_rss_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let kb = s
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse::<u64>()
        .ok()?;
    Some(kb * 1024)
}
