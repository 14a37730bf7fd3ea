//! AFL++ entry point of the `shuffle_block` target ([`hort_fuzz::shuffle_block`]).

fn main() {
    afl::fuzz!(|data: &[u8]| hort_fuzz::shuffle_block(data));
}
