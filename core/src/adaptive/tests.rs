use super::*;

fn settings(base_spp: u32, max_spp: u32, threshold: f64) -> AdaptiveSettings {
    AdaptiveSettings {
        base_spp,
        max_spp,
        threshold,
    }
}

#[test]
fn settings_are_checked_with_one_line_messages() {
    assert!(settings(16, 256, 0.01).check().is_ok());
    assert_eq!(
        settings(12, 256, 0.01).check().unwrap_err().to_string(),
        "adaptive base spp = 12 is out of range: must be a power of 4 from 4 to 16384 (4, 16, 64, 256, ...)"
    );
    assert_eq!(
        settings(1, 256, 0.01).check().unwrap_err().to_string(),
        "adaptive base spp = 1 is out of range: must be a power of 4 from 4 to 16384 (4, 16, 64, 256, ...)"
    );
    assert_eq!(
        settings(16, 128, 0.01).check().unwrap_err().to_string(),
        "adaptive max spp = 128 is out of range: must be a power of 4 above the base spp 16 and at most 65536"
    );
    assert_eq!(
        settings(16, 16, 0.01).check().unwrap_err().to_string(),
        "adaptive max spp = 16 is out of range: must be a power of 4 above the base spp 16 and at most 65536"
    );
    assert_eq!(
        settings(16, 256, f64::NAN).check().unwrap_err().to_string(),
        "adaptive threshold = NaN is out of range: must be a finite number above 0"
    );
    assert_eq!(
        settings(16, 256, 0.0).check().unwrap_err().to_string(),
        "adaptive threshold = 0 is out of range: must be a finite number above 0"
    );
}

/// Cell of a sample on a `cells x cells` grid.
fn cell(p: (f64, f64), cells: u32) -> u32 {
    let c = f64::from(cells);
    (p.1 * c) as u32 * cells + (p.0 * c) as u32
}

/// Every prefix of 4^j ranks puts one sample in each cell of the 2^j x 2^j grid, for the
/// whole pattern too, and one in each of 4^j columns and rows: first pass and first plus
/// second pass are both stratified in 2D and in each 1D projection.
#[test]
fn every_power_of_4_prefix_is_stratified() {
    for max_spp in [4u32, 16, 64, 256, 1024] {
        for pixel in [0u64, 1, 77, 123_456_789] {
            let pts: Vec<_> = (0..max_spp)
                .map(|r| adaptive_offset(pixel, r, max_spp))
                .collect();
            assert!(
                pts.iter()
                    .all(|p| (0.0..1.0).contains(&p.0) && (0.0..1.0).contains(&p.1))
            );
            let mut prefix = 1u32;
            while prefix <= max_spp {
                let side = prefix.isqrt();
                let mut cells: Vec<u32> = pts[..prefix as usize]
                    .iter()
                    .map(|&p| cell(p, side))
                    .collect();
                cells.sort_unstable();
                assert_eq!(
                    cells,
                    (0..prefix).collect::<Vec<_>>(),
                    "max {max_spp}, pixel {pixel}, prefix {prefix}"
                );
                // And one sample in each of `prefix` columns and rows.
                for axis in [0, 1] {
                    let mut strata: Vec<u32> = pts[..prefix as usize]
                        .iter()
                        .map(|p| ([p.0, p.1][axis] * f64::from(prefix)) as u32)
                        .collect();
                    strata.sort_unstable();
                    assert_eq!(strata, (0..prefix).collect::<Vec<_>>(), "axis {axis}");
                }
                prefix *= 4;
            }
        }
    }
}

/// The scrambling differs between pixels (else every pixel would sample the same positions).
#[test]
fn pixels_get_different_patterns() {
    let a: Vec<_> = (0..16).map(|r| adaptive_offset(5, r, 256)).collect();
    let b: Vec<_> = (0..16).map(|r| adaptive_offset(6, r, 256)).collect();
    assert_ne!(a, b);
    assert_eq!(
        a,
        (0..16)
            .map(|r| adaptive_offset(5, r, 256))
            .collect::<Vec<_>>()
    );
}

#[test]
fn decisions_follow_the_standard_error() {
    let constant = [[0.25f32, 0.5, 0.75]; 16];
    assert_eq!(decide(&constant, true, 1e-9), Decision::Converged);
    assert_eq!(decide(&constant, false, 1e-9), Decision::Background);
    // Half the samples 0, half 1 in green: variance 16/60, squared error 1/60 = 0.01667.
    let mut edge = [[0.0f32; 3]; 16];
    for s in edge.iter_mut().take(8) {
        s[1] = 1.0;
    }
    let error = (1.0f64 / 60.0).sqrt();
    assert_eq!(decide(&edge, true, error * 0.999), Decision::Refine);
    assert_eq!(decide(&edge, true, error * 1.001), Decision::Converged);
}

#[test]
fn counts_add_up_samples() {
    let s = settings(4, 64, 0.01);
    let mut counts = AdaptiveCounts::default();
    counts.add(Decision::Refine, &s);
    counts.add(Decision::Background, &s);
    counts.add(Decision::Converged, &s);
    assert_eq!(
        counts,
        AdaptiveCounts {
            refined_pixels: 1,
            background_pixels: 1,
            converged_pixels: 1,
            samples: 64 + 4 + 4,
        }
    );
}
