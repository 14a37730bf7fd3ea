//! AFL++ entry point of the `manifest` target ([`hort_fuzz::manifest`]).

fn main() {
    afl::fuzz!(|data: &[u8]| hort_fuzz::manifest(data));
}
