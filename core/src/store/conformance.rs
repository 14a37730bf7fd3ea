//! The conformance suite every [`BlobStore`] implementation must pass: memory, embedded S3,
//! external S3-compatible services, AWS S3.
//!
//! It is ordinary code (not `cfg(test)`) so that adapter crates and end-to-end tests can run it
//! against their own stores. Each check panics with a message starting `store conformance:` that
//! names the property and the key on the first violation. Every key the suite touches starts with
//! the given `prefix`, so it can run in a shared bucket; it deletes everything under `prefix`
//! before and after running, so give it a prefix of its own (ending in `/`).

use std::fmt::Debug;

use super::{BlobStore, PutOutcome, StoreError};

/// Runs every check below, in order, on a cleared `prefix`, then clears it again.
///
/// # Panics
/// On the first violated property, with a message naming it.
pub fn run_all(store: &dyn BlobStore, prefix: &str) {
    clear(store, prefix);
    get_missing_is_not_found(store, prefix);
    put_get_round_trip(store, prefix);
    overwrite_replaces(store, prefix);
    many_at_once_keep_their_order(store, prefix);
    get_range_clamps_and_rejects(store, prefix);
    put_if_absent_creates_once(store, prefix);
    put_if_absent_race_has_one_winner(store, prefix);
    list_is_sorted_and_exact(store, prefix);
    delete_removes_and_is_idempotent(store, prefix);
    size_and_copy_inside_the_store(store, prefix);
    keys_with_safe_punctuation(store, prefix);
    clear(store, prefix);
    expect_eq(
        "list after clearing the prefix",
        prefix,
        list(store, prefix),
        Vec::<String>::new(),
    );
}

/// Lists more keys than one S3 page holds (1000) and demands all of them, sorted. Slower than
/// [`run_all`] on remote stores (1001 PUTs), so not part of it; run it once per adapter.
pub fn list_returns_every_page(store: &dyn BlobStore, prefix: &str) {
    let base = format!("{prefix}pages/");
    let expected: Vec<String> = (0..1001).map(|i| format!("{base}{i:05}")).collect();
    for key in &expected {
        must("put", key, store.put(key, b"p"));
    }
    expect_eq(
        "list of 1001 keys",
        &base,
        list(store, &base),
        expected.clone(),
    );
    for key in &expected {
        must("delete", key, store.delete(key));
    }
}

/// `get` and `get_range` of a missing key fail with `NotFound` whose message names the key.
pub fn get_missing_is_not_found(store: &dyn BlobStore, prefix: &str) {
    let key = format!("{prefix}missing/object.bin");
    expect_not_found("get of a missing key", &key, store.get(&key));
    expect_not_found(
        "get_range of a missing key",
        &key,
        store.get_range(&key, 0..1),
    );
}

/// Objects of 0 bytes, 1 byte and 3 MiB come back byte for byte.
pub fn put_get_round_trip(store: &dyn BlobStore, prefix: &str) {
    let big: Vec<u8> = (0..3u32 << 20)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
        .collect();
    for (name, bytes) in [
        ("empty", Vec::new()),
        ("one", vec![0xA5]),
        ("three-mib", big),
    ] {
        let key = format!("{prefix}round-trip/{name}");
        must("put", &key, store.put(&key, &bytes));
        let back = must("get after put", &key, store.get(&key));
        expect_bytes("get after put", &key, &back, &bytes);
    }
}

/// `put_many` stores every object and `get_many` returns each key's own result, in order,
/// for more keys than one wave of [`super::PARALLEL_REQUESTS`], a missing key among them.
pub fn many_at_once_keep_their_order(store: &dyn BlobStore, prefix: &str) {
    let objects: Vec<(String, Vec<u8>)> = (0..2 * super::PARALLEL_REQUESTS + 3)
        .map(|i| (format!("{prefix}many/{i:02}"), vec![i as u8; 1000 * i]))
        .collect();
    for (result, (key, _)) in store.put_many(&objects).into_iter().zip(&objects) {
        must("put_many", key, result);
    }
    let mut keys: Vec<String> = objects.iter().map(|(key, _)| key.clone()).collect();
    let missing = format!("{prefix}many/missing");
    keys.insert(5, missing.clone());
    let results = store.get_many(&keys);
    expect_eq("get_many result count", prefix, results.len(), keys.len());
    let mut results = results.into_iter();
    for (i, key) in keys.iter().enumerate() {
        let result = results.next().expect("one result per key");
        if i == 5 {
            expect_not_found("get_many of a missing key", &missing, result);
        } else {
            let back = must("get_many", key, result);
            let (_, want) = &objects[if i < 5 { i } else { i - 1 }];
            expect_bytes("get_many", key, &back, want);
        }
    }
}

/// `size` gives an object's length (0 for an empty one) without its bytes; `copy` stores the
/// source's bytes under the target, replacing what was there, and leaves the source as it was;
/// both are `NotFound` naming the missing source.
pub fn size_and_copy_inside_the_store(store: &dyn BlobStore, prefix: &str) {
    let (from, to) = (format!("{prefix}copy/from"), format!("{prefix}copy/to"));
    let empty = format!("{prefix}copy/empty");
    must("put", &empty, store.put(&empty, b""));
    expect_eq(
        "size of an empty object",
        &empty,
        must("size", &empty, store.size(&empty)),
        0,
    );
    let bytes: Vec<u8> = (0..70_000u32).map(|i| (i % 251) as u8).collect();
    must("put", &from, store.put(&from, &bytes));
    must("put", &to, store.put(&to, b"old"));
    expect_eq(
        "size",
        &from,
        must("size", &from, store.size(&from)),
        70_000,
    );
    must("copy", &from, store.copy(&from, &to));
    expect_bytes(
        "get after copy",
        &to,
        &must("get", &to, store.get(&to)),
        &bytes,
    );
    expect_bytes(
        "source after copy",
        &from,
        &must("get", &from, store.get(&from)),
        &bytes,
    );
    let missing = format!("{prefix}copy/missing");
    expect_not_found("size of a missing key", &missing, store.size(&missing));
    expect_not_found("copy of a missing key", &missing, store.copy(&missing, &to));
}

/// A second `put` replaces the object whole (longer, then shorter).
pub fn overwrite_replaces(store: &dyn BlobStore, prefix: &str) {
    let key = format!("{prefix}overwrite/k");
    for bytes in [&b"first"[..], b"a much longer second value", b"3"] {
        must("put", &key, store.put(&key, bytes));
        let back = must("get after overwrite", &key, store.get(&key));
        expect_bytes("get after overwrite", &key, &back, bytes);
    }
}

/// Ranges inside the object are exact, ranges past its end are clamped, and ranges that are
/// empty or start at or beyond the end are `InvalidRange` naming the key.
pub fn get_range_clamps_and_rejects(store: &dyn BlobStore, prefix: &str) {
    let key = format!("{prefix}range/ten");
    let bytes = b"0123456789";
    must("put", &key, store.put(&key, bytes));
    for (range, want) in [
        (0..10, &bytes[..]),
        (2..5, b"234"),
        (9..10, b"9"),
        (7..100, b"789"),
        (0..u64::MAX, bytes),
    ] {
        let got = must("get_range", &key, store.get_range(&key, range.clone()));
        expect_bytes(&format!("get_range {range:?}"), &key, &got, want);
    }
    let reversed = std::ops::Range { start: 5, end: 2 };
    for range in [10..11, 11..20, 10..u64::MAX, 3..3, reversed] {
        expect_invalid_range(
            &format!("get_range {range:?}"),
            &key,
            store.get_range(&key, range),
        );
    }
    let empty = format!("{prefix}range/empty");
    must("put", &empty, store.put(&empty, b""));
    expect_invalid_range(
        "get_range 0..1 of an empty object",
        &empty,
        store.get_range(&empty, 0..1),
    );
}

/// `put_if_absent` creates a missing object, then reports `AlreadyExists` and leaves the
/// original bytes untouched; it also refuses to replace an object made by a plain `put`.
pub fn put_if_absent_creates_once(store: &dyn BlobStore, prefix: &str) {
    let key = format!("{prefix}once/manifest.json");
    let first = must(
        "put_if_absent",
        &key,
        store.put_if_absent(&key, b"original"),
    );
    expect_eq("first put_if_absent", &key, first, PutOutcome::Created);
    let second = must(
        "put_if_absent",
        &key,
        store.put_if_absent(&key, b"replacement"),
    );
    expect_eq(
        "second put_if_absent",
        &key,
        second,
        PutOutcome::AlreadyExists,
    );
    let back = must("get after put_if_absent", &key, store.get(&key));
    expect_bytes(
        "object after refused put_if_absent",
        &key,
        &back,
        b"original",
    );
    let plain = format!("{prefix}once/plain");
    must("put", &plain, store.put(&plain, b"p"));
    let outcome = must("put_if_absent", &plain, store.put_if_absent(&plain, b"q"));
    expect_eq(
        "put_if_absent over a plain put",
        &plain,
        outcome,
        PutOutcome::AlreadyExists,
    );
}

/// Eight threads racing `put_if_absent` on one key: exactly one `Created`, and the object holds
/// that thread's bytes.
pub fn put_if_absent_race_has_one_winner(store: &dyn BlobStore, prefix: &str) {
    let key = format!("{prefix}race/key");
    let outcomes: Vec<(u8, Result<PutOutcome, StoreError>)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..8u8)
            .map(|i| {
                let key = &key;
                scope.spawn(move || (i, store.put_if_absent(key, &[i; 16])))
            })
            .collect();
        handles.into_iter().filter_map(|h| h.join().ok()).collect()
    });
    let mut winners = Vec::new();
    for (i, outcome) in outcomes {
        if must("racing put_if_absent", &key, outcome) == PutOutcome::Created {
            winners.push(i);
        }
    }
    expect_eq(
        "number of racing put_if_absent winners",
        &key,
        winners.len(),
        1,
    );
    let back = must("get after race", &key, store.get(&key));
    expect_bytes("object after race", &key, &back, &[winners[0]; 16]);
}

/// `list` returns every key under the prefix (deeper levels too), sorted by bytes, and nothing
/// else; an unmatched prefix gives an empty list.
pub fn list_is_sorted_and_exact(store: &dyn BlobStore, prefix: &str) {
    let base = format!("{prefix}list/");
    // Byte order: '-' (0x2d) < '.' (0x2e) < '/' (0x2f) < '0' < '=' < 'A' < '_' < 'a'.
    let names = [
        "b", "a/b/c", "a", "a-b", "a.b", "a/b", "a0", "a=", "aA", "a_", "aa",
    ];
    for name in names {
        let key = format!("{base}{name}");
        must("put", &key, store.put(&key, name.as_bytes()));
    }
    for outside in [
        format!("{prefix}listx/k"),
        format!("{prefix}lis"),
        format!("{prefix}list"),
    ] {
        must("put", &outside, store.put(&outside, b"x"));
    }
    let sorted = [
        "a", "a-b", "a.b", "a/b", "a/b/c", "a0", "a=", "aA", "a_", "aa", "b",
    ];
    let want = |names: &[&str]| {
        names
            .iter()
            .map(|n| format!("{base}{n}"))
            .collect::<Vec<_>>()
    };
    expect_eq("list of a prefix", &base, list(store, &base), want(&sorted));
    let deeper = format!("{base}a/");
    expect_eq(
        "list of a deeper prefix",
        &deeper,
        list(store, &deeper),
        want(&["a/b", "a/b/c"]),
    );
    let partial = format!("{base}a");
    expect_eq(
        "list of a partial name",
        &partial,
        list(store, &partial),
        want(&sorted[..10]),
    );
    let none = format!("{base}zzz");
    expect_eq(
        "list with no match",
        &none,
        list(store, &none),
        Vec::<String>::new(),
    );
}

/// After `delete`, `get` is `NotFound` and the key leaves listings; deleting a missing key (or
/// the same key twice) succeeds.
pub fn delete_removes_and_is_idempotent(store: &dyn BlobStore, prefix: &str) {
    let base = format!("{prefix}delete/");
    let (key, kept) = (format!("{base}gone"), format!("{base}kept"));
    must("put", &key, store.put(&key, b"x"));
    must("put", &kept, store.put(&kept, b"y"));
    must("delete", &key, store.delete(&key));
    expect_not_found("get after delete", &key, store.get(&key));
    expect_eq(
        "list after delete",
        &base,
        list(store, &base),
        vec![kept.clone()],
    );
    must("delete of a deleted key", &key, store.delete(&key));
    let never = format!("{base}never-existed");
    must("delete of a missing key", &never, store.delete(&never));
    let back = must("get of a neighbour", &kept, store.get(&kept));
    expect_bytes("neighbour of a deleted key", &kept, &back, b"y");
}

/// Keys using every S3-safe character the project uses (`a-z A-Z 0-9 / - _ . =`) round-trip
/// through put, get and list unchanged.
pub fn keys_with_safe_punctuation(store: &dyn BlobStore, prefix: &str) {
    let base = format!("{prefix}chars/");
    let names = [
        "k=v/x-y_z.bin",
        "UPPER.lower_09",
        "a..b",
        "x/y/z/part-00001",
        "=_-.",
    ];
    let mut keys: Vec<String> = names.iter().map(|n| format!("{base}{n}")).collect();
    for key in &keys {
        must("put", key, store.put(key, key.as_bytes()));
        let back = must("get", key, store.get(key));
        expect_bytes("get of a punctuated key", key, &back, key.as_bytes());
    }
    keys.sort();
    expect_eq("list of punctuated keys", &base, list(store, &base), keys);
}

/// Deletes every key under `prefix`.
fn clear(store: &dyn BlobStore, prefix: &str) {
    for key in list(store, prefix) {
        must("delete while clearing", &key, store.delete(&key));
    }
}

fn list(store: &dyn BlobStore, prefix: &str) -> Vec<String> {
    must("list", prefix, store.list(prefix))
}

fn must<T>(what: &str, key: &str, result: Result<T, StoreError>) -> T {
    result.unwrap_or_else(|e| panic!("store conformance: {what} of {key:?} failed: {e}"))
}

fn expect_eq<T: PartialEq + Debug>(what: &str, key: &str, got: T, want: T) {
    assert!(
        got == want,
        "store conformance: {what} ({key:?}): got {got:?}, want {want:?}"
    );
}

fn expect_bytes(what: &str, key: &str, got: &[u8], want: &[u8]) {
    if got != want {
        let at = got.iter().zip(want).position(|(a, b)| a != b);
        panic!(
            "store conformance: {what} ({key:?}): got {} bytes, want {}; first difference at {at:?}",
            got.len(),
            want.len()
        );
    }
}

fn expect_not_found<T: Debug>(what: &str, key: &str, result: Result<T, StoreError>) {
    match result {
        Err(e @ StoreError::NotFound { .. }) => {
            let msg = e.to_string();
            assert!(
                msg.contains(key),
                "store conformance: {what}: message {msg:?} does not name {key:?}"
            );
        }
        other => panic!("store conformance: {what} ({key:?}): want NotFound, got {other:?}"),
    }
}

fn expect_invalid_range<T: Debug>(what: &str, key: &str, result: Result<T, StoreError>) {
    match result {
        Err(e @ StoreError::InvalidRange { .. }) => {
            let msg = e.to_string();
            assert!(
                msg.contains(key),
                "store conformance: {what}: message {msg:?} does not name {key:?}"
            );
        }
        other => panic!("store conformance: {what} ({key:?}): want InvalidRange, got {other:?}"),
    }
}

#[cfg(test)]
mod tests;
