//! AFL++ entry point of the `http` target ([`hort_fuzz::http`]).

fn main() {
    afl::fuzz!(|data: &[u8]| hort_fuzz::http(data));
}
