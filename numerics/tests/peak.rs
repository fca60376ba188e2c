//! `memory::reset_peak` (alone in its test binary: no other test's allocations in the process).

use ves_numerics::memory;

/// After 256 MiB touched and freed, the peak stays up; reset, it is the process's size again.
#[test]
fn the_peak_resident_size_is_reset_to_the_current_size() {
    let before = memory::peak_rss_bytes();
    let big = vec![1u8; 256 << 20];
    // Touched: every page resident.
    assert_eq!(
        big.iter().step_by(4096).map(|&b| u64::from(b)).sum::<u64>(),
        (256 << 20) / 4096
    );
    let peak = memory::peak_rss_bytes();
    drop(big);
    memory::release_free_memory();
    assert!(peak >= before + (200 << 20), "peak {peak} before {before}");
    assert!(memory::reset_peak(), "/proc/self/clear_refs (Linux 4.0 and later)");
    let after = memory::peak_rss_bytes();
    assert!(after + (200 << 20) <= peak, "after reset {after}, peak was {peak}");
}
