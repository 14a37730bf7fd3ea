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
    assert!(
        settings(3, 5, 0.01).check().is_ok(),
        "any counts, not only powers of 4"
    );
    assert!(settings(2, 65_536, 0.01).check().is_ok());
    assert_eq!(
        settings(1, 256, 0.01).check().unwrap_err().to_string(),
        "adaptive base spp = 1 is out of range: must be from 2 (a pixel's error estimate needs two samples) to 65535"
    );
    assert_eq!(
        settings(65_536, 65_536, 0.01)
            .check()
            .unwrap_err()
            .to_string(),
        "adaptive base spp = 65536 is out of range: must be from 2 (a pixel's error estimate needs two samples) to 65535"
    );
    assert_eq!(
        settings(16, 16, 0.01).check().unwrap_err().to_string(),
        "adaptive max spp = 16 is out of range: must be above the base spp 16 and at most 65536"
    );
    assert_eq!(
        settings(16, 65_537, 0.01).check().unwrap_err().to_string(),
        "adaptive max spp = 65537 is out of range: must be above the base spp 16 and at most 65536"
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
