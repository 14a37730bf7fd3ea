//! AFL++ entry point of the `http` target ([`hort_fuzz::http`]).

#[path = "../capped_alloc.rs"]
mod capped_alloc;

#[global_allocator]
static ALLOCATOR: capped_alloc::Capped = capped_alloc::Capped;

fn main() {
    afl::fuzz!(|data: &[u8]| hort_fuzz::http(data));
}
