//! Error of an image against a reference, on linear values.
//!
//! Over all N = width x height x 3 channel values x (the image) and r (the reference), in f64:
//! - RMSE = sqrt(sum (x - r)^2 / N);
//! - relative MSE = sum ((x - r)^2 / (r^2 + 0.01)) / N (the 0.01 keeps black pixels finite);
//! - PSNR = 10 log10(1 / MSE) dB, peak 1 (the radiance of a white surface facing the default
//!   light at the scene centre); infinite when the images are equal.
//!
//! `eval/mitsuba_refs.py` computes Mitsuba's errors with the same definitions.

use hort_core::image::Image;

/// The `relMSE` denominator guard added to `r^2`.
pub const RELMSE_EPS: f64 = 1e-2;

/// The three error measures of one image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Errors {
    /// Root mean squared error.
    pub rmse: f64,
    /// Relative mean squared error.
    pub relmse: f64,
    /// Peak signal-to-noise ratio in dB, peak 1; `inf` for equal images.
    pub psnr: f64,
}

/// The errors of `image` against `reference`; an error naming both sizes when they differ.
pub fn errors(image: &Image, reference: &Image) -> Result<Errors, String> {
    if (image.width, image.height) != (reference.width, reference.height)
        || image.pixels.len() != reference.pixels.len()
    {
        return Err(format!(
            "the image is {}x{} but the reference is {}x{}",
            image.width, image.height, reference.width, reference.height
        ));
    }
    if image.pixels.is_empty() {
        return Err("the image has no pixels".into());
    }
    let (mut squared, mut relative) = (0.0f64, 0.0f64);
    for (x, r) in image.pixels.iter().zip(&reference.pixels) {
        for c in 0..3 {
            let (x, r) = (f64::from(x[c]), f64::from(r[c]));
            let d2 = (x - r) * (x - r);
            squared += d2;
            relative += d2 / (r * r + RELMSE_EPS);
        }
    }
    let n = (image.pixels.len() * 3) as f64;
    let mse = squared / n;
    Ok(Errors {
        rmse: mse.sqrt(),
        relmse: relative / n,
        psnr: psnr_of_mse(mse),
    })
}

/// PSNR in dB of a mean squared error, peak 1.
pub fn psnr_of_mse(mse: f64) -> f64 {
    if mse == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: u32, height: u32, pixels: Vec<[f32; 3]>) -> Image {
        Image {
            width,
            height,
            pixels,
        }
    }

    #[test]
    fn hand_computed_values() {
        // Differences 0.5 on one channel of six: MSE = 0.25 / 6, relMSE = (0.25 / 1.01) / 6.
        let reference = image(2, 1, vec![[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]);
        let x = image(2, 1, vec![[0.5, 0.0, 0.0], [0.0, 0.0, 0.0]]);
        let e = errors(&x, &reference).unwrap();
        assert_eq!(e.rmse, (0.25f64 / 6.0).sqrt());
        assert_eq!(e.relmse, 0.25 / 1.01 / 6.0);
        assert_eq!(e.psnr, -10.0 * (0.25f64 / 6.0).log10());
    }

    #[test]
    fn a_black_reference_pixel_weighs_by_the_guard() {
        // (0.1)^2 / (0 + 0.01) = 1 for each of the three values.
        let reference = image(1, 1, vec![[0.0; 3]]);
        let x = image(1, 1, vec![[0.1; 3]]);
        let e = errors(&x, &reference).unwrap();
        assert_eq!(e.relmse, (0.1f32 as f64).powi(2) / 0.01);
        assert_eq!(e.rmse, 0.1f32 as f64);
    }

    #[test]
    fn psnr_of_a_uniform_error_of_a_tenth_is_20_db() {
        assert_eq!(psnr_of_mse(0.01), 20.0);
        assert_eq!(psnr_of_mse(1.0), 0.0);
    }

    #[test]
    fn equal_images_have_zero_error_and_infinite_psnr() {
        let a = image(1, 2, vec![[0.3, 0.2, 0.1], [1.0, 2.0, 3.0]]);
        let e = errors(&a, &a).unwrap();
        assert_eq!((e.rmse, e.relmse), (0.0, 0.0));
        assert_eq!(e.psnr, f64::INFINITY);
    }

    #[test]
    fn different_sizes_are_refused_with_both_sizes() {
        let a = image(2, 1, vec![[0.0; 3]; 2]);
        let b = image(1, 2, vec![[0.0; 3]; 2]);
        assert_eq!(
            errors(&a, &b).unwrap_err(),
            "the image is 2x1 but the reference is 1x2"
        );
    }
}
