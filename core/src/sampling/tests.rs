use super::*;

#[test]
fn one_sample_is_the_pixel_centre() {
    assert_eq!(sample_offset(7, 0, 1), (0.5, 0.5));
    assert_eq!(sample_offset(7, 0, 0), (0.5, 0.5));
    let (x, y) = PixelSamples::new(7, 1).offsets_lanes(&SampleRun::new([0, 1, 2, 3]));
    assert_eq!((x, y), ([0.5; 4], [0.5; 4]));
}

/// A sample's position does not depend on the pixel's sample count (above 1): the first n
/// samples of any count are the same n samples.
#[test]
fn samples_do_not_depend_on_the_count() {
    for pixel in [0u64, 1, 77, 12_345, u64::MAX] {
        for sample in 0..300u32 {
            let at = |spp: u32| {
                let (x, y) = sample_offset(pixel, sample, spp);
                (x.to_bits(), y.to_bits())
            };
            let reference = at(2);
            for spp in [3u32, 12, 96, 301, 65_536] {
                assert_eq!(
                    at(spp),
                    reference,
                    "pixel {pixel} sample {sample} spp {spp}"
                );
            }
        }
    }
}

/// Every prefix of n samples is stratified as well as n points can be: in each partition of
/// the pixel into 2^k dyadic boxes of equal shape (columns, rows, squares and everything in
/// between), every box holds floor(n / 2^k) or ceil(n / 2^k) samples. Samples lie in [0, 1).
#[test]
fn every_prefix_is_stratified_in_every_dyadic_partition() {
    for pixel in [0u64, 1, 77, 123_456_789] {
        let samples = PixelSamples::new(pixel, 2);
        let points: Vec<(f64, f64)> = (0..300).map(|s| samples.offset(s)).collect();
        assert!(
            points
                .iter()
                .all(|p| (0.0..1.0).contains(&p.0) && (0.0..1.0).contains(&p.1))
        );
        for n in 1..=points.len() {
            for k in 0..=8u32 {
                let boxes = 1usize << k;
                let (low, high) = (n / boxes, n.div_ceil(boxes));
                for a in 0..=k {
                    let (columns, rows) = (f64::from(1u32 << a), f64::from(1u32 << (k - a)));
                    let mut counts = vec![0usize; boxes];
                    for &(x, y) in &points[..n] {
                        let (bx, by) = ((x * columns) as usize, (y * rows) as usize);
                        counts[bx * (1 << (k - a)) + by] += 1;
                    }
                    assert!(
                        counts.iter().all(|&c| c == low || c == high),
                        "pixel {pixel}, {n} samples, {columns} x {rows} boxes: {counts:?}"
                    );
                }
            }
        }
    }
}

/// Four consecutive offsets in lanes, and sixteen spread ones, are the single offsets bit for
/// bit, also at the end of the u32 range (wrapping) and for the one-sample centre.
#[test]
fn offsets_in_lanes_are_the_single_offsets() {
    for spp in [1u32, 2, 3, 64, 96] {
        for pixel in [0u64, 1, 77, 12_345, u64::MAX] {
            let samples = PixelSamples::new(pixel, spp);
            let starts = (0..spp + 8).chain([1023, u32::MAX - 5, u32::MAX - 3, u32::MAX]);
            for first in starts {
                let four: [u32; 4] = std::array::from_fn(|k| first.wrapping_add(k as u32));
                let (xs, ys) = samples.offsets_lanes(&SampleRun::new(four));
                for (k, (x, y)) in xs.into_iter().zip(ys).enumerate() {
                    let (ex, ey) = samples.offset(first.wrapping_add(k as u32));
                    assert_eq!(
                        (x.to_bits(), y.to_bits()),
                        (ex.to_bits(), ey.to_bits()),
                        "spp {spp} pixel {pixel} sample {first} + {k}"
                    );
                }
                let lanes: [u32; 16] = std::array::from_fn(|k| first.wrapping_add(3 * k as u32));
                let (xs, ys) = samples.offsets_lanes(&SampleRun::new(lanes));
                for k in 0..16 {
                    let (ex, ey) = samples.offset(lanes[k]);
                    assert_eq!(
                        (xs[k].to_bits(), ys[k].to_bits()),
                        (ex.to_bits(), ey.to_bits()),
                        "spp {spp} pixel {pixel} sample {} (sixteen lanes)",
                        lanes[k]
                    );
                }
            }
        }
    }
}

/// Neighbouring pixels get different scrambles (no pattern repeats across the image): the
/// first sample of 1,000 pixels takes 1,000 distinct positions.
#[test]
fn pixels_are_scrambled_independently() {
    let mut first: Vec<(u64, u64)> = (0..1000u64)
        .map(|p| {
            let (x, y) = sample_offset(p, 0, 4);
            (x.to_bits(), y.to_bits())
        })
        .collect();
    first.sort_unstable();
    first.dedup();
    assert_eq!(first.len(), 1000);
}
