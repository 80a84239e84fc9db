//! The memory check before a big run: refuse work that would not fit (exit 2 before any work)
//! instead of letting the allocator abort it halfway.

use crate::{Error, Result};

/// Bytes this process may still allocate: the smaller of the memory the system has available
/// and the room left under its address-space limit (`ulimit -v`). `None` where neither is known.
pub fn memory_available() -> Option<u64> {
    let field = |text: &str, key: &str| -> Option<u64> {
        let line = text.lines().find(|l| l.starts_with(key))?;
        line.split_whitespace().nth(1)?.parse::<u64>().ok()
    };
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok();
    let avail = meminfo
        .as_deref()
        .and_then(|t| field(t, "MemAvailable:"))
        .map(|kb| kb * 1024);
    let limits = std::fs::read_to_string("/proc/self/limits").ok();
    let as_limit = limits.as_deref().and_then(|t| {
        let l = t.lines().find(|l| l.starts_with("Max address space"))?;
        l.split_whitespace().nth(3)?.parse::<u64>().ok() // "unlimited" does not parse
    });
    let vm_now = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|t| field(&t, "VmSize:"))
        .map(|kb| kb * 1024)
        .unwrap_or(0);
    // address space is reserved beyond what is touched (thread stacks, malloc arenas)
    let room = as_limit.map(|l| l.saturating_sub(vm_now).saturating_sub(256 << 20));
    match (avail, room) {
        (Some(a), Some(r)) => Some(a.min(r)),
        (a, r) => a.or(r),
    }
}

/// Refuses a run that needs more memory than the process may use (exit 2, before any work),
/// instead of letting the allocator abort it halfway.
pub fn check_memory(what: &str, need: u64, available: Option<u64>) -> Result<()> {
    let gb = |b: u64| b as f64 / 1e9;
    match available {
        Some(a) if need > a => Err(Error::Invalid(format!(
            "{what} needs about {:.1} GB of memory, but this process may use {:.1} GB (free memory, ulimit -v); make it smaller",
            gb(need),
            gb(a)
        ))),
        _ => Ok(()),
    }
}

/// Memory a run needs for `pixels` pixels at `bytes_per_pixel`, plus the program itself.
/// The rates are peak resident sizes measured on renders of 1000² and 3000² pixels (docs/reliability.md).
pub fn memory_need(pixels: usize, bytes_per_pixel: u64) -> u64 {
    pixels as u64 * bytes_per_pixel + (64 << 20)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_check_names_what_is_needed() {
        assert!(check_memory("x", 10, None).is_ok());
        assert!(check_memory("x", 10, Some(11)).is_ok());
        let e =
            check_memory("render 10000 x 10000", 7_200_000_000, Some(3_900_000_000)).unwrap_err();
        assert!(e.is_usage());
        assert!(e.to_string().contains("needs about 7.2 GB"), "{e}");
        assert!(memory_available().is_some_and(|a| a > 0));
    }
}
