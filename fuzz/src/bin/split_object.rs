//! AFL++ entry point of the `split_object` target ([`hort_fuzz::split_object`]).

fn main() {
    afl::fuzz!(|data: &[u8]| hort_fuzz::split_object(data));
}
