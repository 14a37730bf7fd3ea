//! AFL++ entry point of the `manifest` target ([`hort_fuzz::manifest`]).

#[path = "../capped_alloc.rs"]
mod capped_alloc;

#[global_allocator]
static ALLOCATOR: capped_alloc::Capped = capped_alloc::Capped;

fn main() {
    afl::fuzz!(|data: &[u8]| hort_fuzz::manifest(data));
}
