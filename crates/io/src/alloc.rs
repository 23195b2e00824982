//! How the process takes memory from the system while it reads ([`tune_memory`]): freed memory
//! kept for the next allocation instead of handed back and faulted in again, and no transparent
//! huge pages.
//!
//! Why: reading a 31 M-row campaign allocates and frees the same buffers over and over (a
//! column chunk's bytes, its pages decompressed, a batch's arrays), and every page first
//! touched is a fault and a page the kernel zeroes. On the reference VM a fault costs far more
//! than the zeroing (profile of `dbbcal identify` on the shuffled 1 Hz layout: the kernel's
//! `clear_page_erms` under huge-page faults was 30 % of the samples, the largest entry). Three
//! settings:
//! - mimalloc, the binary's global allocator (`src/main.rs`), purges freed pages after a delay
//!   (`purge_delay`, 1 s in mimalloc 3); ingest and identify would reuse them after that time
//!   and fault them in again. Its purge delay is set to "never".
//! - glibc's `malloc` serves the C libraries the parquet crate links: zstd's contexts are
//!   created for every column chunk of every row group (`parquet::compression`'s codec, one per
//!   column reader) and freed after it, and glibc maps large blocks afresh or trims them from
//!   its heap's top when freed (dynamic thresholds from 128 KB): 7 200 page faults a pass over
//!   the 240 row groups of a 1 Hz campaign (`crates/io/examples/decode_floor.rs`, shuffled
//!   layout), 440 in six passes with the thresholds raised.
//! - Transparent huge pages: mimalloc asks for them on its arenas (`madvise`), so every first
//!   touch of 2 MiB zeroes 2 MiB at once, used or not. Off for the process
//!   (`PR_SET_THP_DISABLE`, what mimalloc's own `allow_thp = 0` does when read at its start;
//!   inherited by the supervised child): `identify` on the shuffled 1 Hz layout, 1.1-1.6 s of
//!   system time with them, 0.43-0.63 s without (three runs each, load 2.4-2.9), the same user
//!   time and peak RSS within the noise.
//!
//! Memory: what is kept is what was in use before, so the peak is unchanged up to
//! fragmentation (`bench/README.md`, "The 1 Hz layouts", measures peak RSS). That can be much:
//! on the diagnosis of a 10-s campaign read at every reading (the second simulator's k = 3,
//! seed 4) the peak RSS was about 930 MiB where the pages in use peaked at about 730 MiB
//! (`MIMALLOC_PURGE_DELAY=0`); returned after 1 s instead, the run took 10 % longer
//! (`bench/README.md`, "The fifth session of the day"). Nothing here changes a result.

use std::ffi::{c_int, c_long};

// The crate that builds and links mimalloc's library, whose option table is set below.
use mimalloc as _;

/// mimalloc's `mi_option_purge_delay` (its `mimalloc.h`, the same index in mimalloc 2 and 3).
const MI_OPTION_PURGE_DELAY: c_int = 15;

extern "C" {
    /// mimalloc's own API (`mimalloc.h`), in the library the `mimalloc` crate links: sets an
    /// option's value unless the environment (`MIMALLOC_PURGE_DELAY`) set it.
    fn mi_option_set_default(option: c_int, value: c_long);
}

/// glibc's heap keeps freed memory up to this much at its top (`M_TRIM_THRESHOLD`).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const GLIBC_TRIM_THRESHOLD: c_int = 1 << 30;
/// Blocks below this come from glibc's heap, not a mapping of their own
/// (`M_MMAP_THRESHOLD`; 32 MiB is glibc's largest on 64-bit systems).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const GLIBC_MMAP_THRESHOLD: c_int = 32 << 20;

/// Sets how the process takes memory (module doc): mimalloc never purges freed pages (unless
/// `MIMALLOC_PURGE_DELAY` says otherwise), glibc's `malloc` (used by the C decoders) takes
/// blocks below 32 MiB from its heap and returns the heap's top only beyond 1 GiB, and no
/// transparent huge pages. Call it first thing in `main`, before any thread starts. It changes
/// no result, only how often memory is faulted in and zeroed.
pub fn tune_memory() {
    // SAFETY: a plain setter of an integer option in mimalloc's option table; valid at any
    // time, and called before any other thread exists.
    unsafe { mi_option_set_default(MI_OPTION_PURGE_DELAY, -1) };
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only sets glibc's malloc parameters; called before any other thread.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, GLIBC_MMAP_THRESHOLD);
        libc::mallopt(libc::M_TRIM_THRESHOLD, GLIBC_TRIM_THRESHOLD);
    }
    #[cfg(target_os = "linux")]
    // SAFETY: sets one flag of this process (and the processes it starts); a kernel without
    // it returns an error, which leaves everything as it was.
    unsafe {
        libc::prctl(libc::PR_SET_THP_DISABLE, 1, 0, 0, 0);
    }
}
