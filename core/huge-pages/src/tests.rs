use super::*;

#[test]
fn it_is_an_empty_vec_with_the_capacity_asked_for() {
    for capacity in [
        0,
        1,
        1000,
        MIN_ADVISED_BYTES / 8 - 1,
        MIN_ADVISED_BYTES,
        3 << 20,
    ] {
        let mut array: Vec<u64> = vec_with_capacity(capacity);
        assert!(array.is_empty());
        assert!(array.capacity() >= capacity, "capacity {capacity}");
        array.extend((0..capacity as u64).map(|x| x * 3));
        assert!(array.iter().enumerate().all(|(i, &x)| x == 3 * i as u64));
    }
    let empty: Vec<()> = vec_with_capacity(1 << 30);
    assert!(empty.is_empty());
}

/// The kernel's transparent huge page mode (`always`, `madvise` or `never`), if it has them.
#[cfg(target_os = "linux")]
fn huge_page_mode() -> Option<String> {
    let modes = std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled").ok()?;
    let start = modes.find('[')? + 1;
    let end = start + modes[start..].find(']')?;
    Some(modes[start..end].to_string())
}

/// The kB of anonymous huge pages backing the mapping that holds `address` (from
/// `/proc/self/smaps`).
#[cfg(target_os = "linux")]
fn huge_kb_at(address: usize) -> u64 {
    let smaps = std::fs::read_to_string("/proc/self/smaps").expect("smaps is readable");
    let mut inside = false;
    for line in smaps.lines() {
        let first = line.split_whitespace().next().unwrap_or("");
        if let Some((lo, hi)) = first.split_once('-')
            && let (Ok(lo), Ok(hi)) = (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16))
        {
            inside = (lo..hi).contains(&address);
        } else if inside && let Some(kb) = line.strip_prefix("AnonHugePages:") {
            return kb
                .trim()
                .trim_end_matches("kB")
                .trim()
                .parse()
                .expect("a kB count");
        }
    }
    panic!("no mapping holds {address:#x}");
}

#[cfg(target_os = "linux")]
#[test]
fn a_filled_array_is_backed_by_huge_pages_where_the_kernel_offers_them() {
    let Some(mode) = huge_page_mode() else {
        eprintln!("this kernel has no transparent huge pages: nothing to check");
        return;
    };
    let bytes = 16 << 20;
    let mut advised: Vec<u8> = vec_with_capacity(bytes);
    advised.resize(bytes, 1);
    let mut plain: Vec<u8> = Vec::with_capacity(bytes);
    plain.resize(bytes, 1);
    let middle = |a: &Vec<u8>| a.as_ptr() as usize + bytes / 2;
    let (advised_kb, plain_kb) = (huge_kb_at(middle(&advised)), huge_kb_at(middle(&plain)));
    match mode.as_str() {
        "never" => assert_eq!(advised_kb, 0),
        "madvise" => {
            assert!(
                advised_kb > 0,
                "the advised array has no huge pages (or the kernel found no free 2 MiB page)"
            );
            assert_eq!(plain_kb, 0, "an array nobody advised has huge pages");
        }
        _ => assert!(
            advised_kb > 0,
            "the advised array has no huge pages (mode {mode})"
        ),
    }
}
