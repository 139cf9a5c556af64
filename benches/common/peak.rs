//! The process's resident memory and its peak, from Linux' /proc (kB), for
//! the benches that report memory; None elsewhere.
#![allow(dead_code)] // each bench uses the part it reports

fn field(name: &str) -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(name))?;
    line[name.len()..]
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()
}

/// Resets the peak to the memory resident now, and returns that.
pub fn reset() -> Option<f64> {
    std::fs::write("/proc/self/clear_refs", "5").ok()?;
    field("VmRSS:")
}

/// The peak since the last reset.
pub fn high_water() -> Option<f64> {
    field("VmHWM:")
}
