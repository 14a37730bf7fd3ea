//! AFL++ entry point of the `obj` target ([`hort_fuzz::obj`]).

fn main() {
    afl::fuzz!(|data: &[u8]| hort_fuzz::obj(data));
}
