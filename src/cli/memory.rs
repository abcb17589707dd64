//! Resident memory of this process from `/proc/self/status` (Linux): the current resident
//! set (VmRSS) and its peak (VmHWM), and the peak's reset through `/proc/self/clear_refs`
//! so that the peak of one step can be measured.

use serde::Serialize;

/// Bytes in a kibibyte, the unit of `/proc/self/status`.
const BYTES_PER_KIB: f64 = 1024.0;
/// Bytes in a mebibyte, the unit reported.
const BYTES_PER_MIB: f64 = 1024.0 * 1024.0;

/// Resident memory now and at its peak, MiB.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Resident {
    /// VmRSS, MiB.
    pub current_mib: f64,
    /// VmHWM (peak since start or the last reset), MiB.
    pub peak_mib: f64,
}

/// Reads VmRSS and VmHWM; `None` where `/proc` is unavailable.
pub fn resident() -> Option<Resident> {
    parse_status(&std::fs::read_to_string("/proc/self/status").ok()?)
}

fn parse_status(status: &str) -> Option<Resident> {
    let field = |name: &str| -> Option<f64> {
        let line = status.lines().find(|l| l.starts_with(name))?;
        let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kib * BYTES_PER_KIB / BYTES_PER_MIB)
    };
    Some(Resident {
        current_mib: field("VmRSS:")?,
        peak_mib: field("VmHWM:")?,
    })
}

/// Resets VmHWM to the current resident set; false when the kernel refuses.
pub fn reset_peak() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// Memory used by one step: the process peak during it and its growth over the resident
/// set at its start.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StepMemory {
    /// Resident set when the step started, MiB.
    pub start_mib: f64,
    /// Peak resident set during the step, MiB (since process start when `peak_reset` is
    /// false).
    pub peak_mib: f64,
    /// `peak_mib − start_mib`: what the step added at most, MiB.
    pub growth_mib: f64,
    /// Whether the peak was reset at the start of the step.
    pub peak_reset: bool,
}

/// Runs `step` and measures its memory (`None` without `/proc`).
pub fn measure<T>(step: impl FnOnce() -> T) -> (T, Option<StepMemory>) {
    let peak_reset = reset_peak();
    let start = resident();
    let out = step();
    let memory = start.zip(resident()).map(|(s, e)| StepMemory {
        start_mib: s.current_mib,
        peak_mib: e.peak_mib,
        growth_mib: (e.peak_mib - s.current_mib).max(0.0),
        peak_reset,
    });
    (out, memory)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_status_fields_in_mib() {
        let status = "Name:\tx\nVmHWM:\t  20480 kB\nVmRSS:\t   10240 kB\n";
        assert_eq!(
            parse_status(status),
            Some(Resident {
                current_mib: 10.0,
                peak_mib: 20.0
            })
        );
        assert_eq!(parse_status("Name:\tx\n"), None);
    }

    #[test]
    fn a_large_allocation_shows_in_the_growth() {
        let (len, memory) = measure(|| {
            let block = vec![1u8; 64 << 20];
            std::hint::black_box(&block)
                .iter()
                .map(|&b| b as usize)
                .sum::<usize>()
        });
        assert_eq!(len, 64 << 20);
        if let Some(m) = memory.filter(|m| m.peak_reset) {
            assert!(m.growth_mib > 32.0, "{m:?}");
        }
    }
}
