//! AFL++ entry point of the `asl` target ([`hort_fuzz::asl`]).

fn main() {
    afl::fuzz!(|data: &[u8]| hort_fuzz::asl(data));
}
