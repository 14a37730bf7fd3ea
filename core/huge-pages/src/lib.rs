//! Large arrays that are filled right after they are allocated (a decoded split's nodes,
//! triangle packs and ids), with the kernel asked to back them with transparent huge pages.
//!
//! Filling fresh memory costs a page fault per page: with 4 KiB pages that is most of the time
//! of writing an array once (on the 2-core Firecracker VM this was measured on, a copy of 78 MB
//! into a fresh `Vec` took 36 to 43 ms, mostly its 19,000 page faults, each of which also zeroes
//! its page). With the block advised `MADV_HUGEPAGE` the kernel faults in 2 MiB at a time: the
//! same copy took 9.2 to 9.9 ms.
//!
//! # Guarantees
//!
//! [`vec_with_capacity`] returns exactly what `Vec::with_capacity` returns (same capacity, same
//! allocator, same contents as it is filled); only how the kernel backs the pages may differ.
//! The advice is given on Linux for blocks of at least [`MIN_ADVISED_BYTES`], and only for the
//! whole pages inside the block, so memory of other allocations is never advised. Where the
//! kernel declines it (transparent huge pages set to `never` or not built in, another operating
//! system), nothing changes. Memory: a huge page is backed whole once any byte of it is
//! touched, so an array filled only partly may hold up to one huge page more than it uses; a
//! filled array holds what it would anyway.

#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]

/// The smallest block worth advising: one huge page (2 MiB on x86-64 and on arm64 with 4 KiB
/// pages); a smaller block cannot hold an aligned huge page.
pub const MIN_ADVISED_BYTES: usize = 2 << 20;

/// `Vec::with_capacity(capacity)`, with its block advised to use transparent huge pages when it
/// is at least [`MIN_ADVISED_BYTES`] (see the [crate documentation](crate)). Meant for arrays
/// filled soon after, front to back: advice costs one system call.
pub fn vec_with_capacity<T>(capacity: usize) -> Vec<T> {
    let mut array: Vec<T> = Vec::with_capacity(capacity);
    let bytes = array.capacity().saturating_mul(size_of::<T>());
    if bytes >= MIN_ADVISED_BYTES {
        advise(array.as_mut_ptr().cast::<u8>(), bytes);
    }
    array
}

/// Advises the whole pages of the block at `start`, `bytes` long, to use huge pages.
#[cfg(target_os = "linux")]
fn advise(start: *mut u8, bytes: usize) {
    // SAFETY: sysconf reads a constant of the system and touches no memory of ours.
    let page = match unsafe { libc::sysconf(libc::_SC_PAGESIZE) } {
        p if p > 0 => p as usize,
        _ => return,
    };
    let address = start as usize;
    let first = address.next_multiple_of(page) - address;
    let end = (address + bytes) / page * page - address;
    if end <= first {
        return;
    }
    // SAFETY: the range is whole pages inside one live allocation this function's caller owns
    // (the `Vec`'s block), and MADV_HUGEPAGE changes only how the kernel backs those pages,
    // never their contents or whether they are mapped. A refusal (EINVAL where huge pages are
    // not built in) leaves everything as it was, so the result is not needed.
    unsafe {
        libc::madvise(
            start.wrapping_add(first).cast::<libc::c_void>(),
            end - first,
            libc::MADV_HUGEPAGE,
        );
    }
}

/// No advice elsewhere.
#[cfg(not(target_os = "linux"))]
fn advise(_start: *mut u8, _bytes: usize) {}

#[cfg(test)]
mod tests;
