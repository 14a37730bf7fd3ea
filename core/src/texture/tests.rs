use super::*;

/// A `w` x `h` texture whose texel (x, y) has red x, green y and blue 7.
fn ramp(w: u32, h: u32) -> Texture {
    let texels = (0..h)
        .flat_map(|y| (0..w).flat_map(move |x| [x as u8, y as u8, 7]))
        .collect();
    Texture::new("ramp.png".into(), w, h, texels)
}

#[test]
fn the_srgb_table_decodes_the_ends_and_the_middle() {
    let t = srgb_to_linear_table();
    assert_eq!(t[0], 0.0);
    assert_eq!(t[255], 1.0);
    // 0.5 in sRGB is 0.214 linear (IEC 61966-2-1).
    assert!((t[128] - 0.2158605).abs() < 1e-6, "{}", t[128]);
    assert!(t.windows(2).all(|w| w[0] < w[1]));
}

#[test]
fn a_texel_centre_reads_that_texel_and_v_runs_up_the_image() {
    let t = ramp(4, 2);
    let lut = srgb_to_linear_table();
    // Texel (1, 0) is in the top row: v near 1.
    let c = t.sample([1.5 / 4.0, 1.0 - 0.5 / 2.0]);
    assert_eq!(c, [lut[1], lut[0], lut[7]]);
    // Texel (2, 1) is in the bottom row: v near 0.
    let c = t.sample([2.5 / 4.0, 0.5 / 2.0]);
    assert_eq!(c, [lut[2], lut[1], lut[7]]);
}

#[test]
fn halfway_between_centres_is_the_mean_and_edges_wrap() {
    let t = ramp(4, 1);
    let lut = srgb_to_linear_table();
    let c = t.sample([2.0 / 4.0, 0.5]);
    assert_eq!(c[0], 0.5 * lut[1] + 0.5 * lut[2]);
    // u = 0 lies between the last texel's centre and the first's.
    let c = t.sample([0.0, 0.5]);
    assert_eq!(c[0], 0.5 * lut[3] + 0.5 * lut[0]);
    // Whole periods away, the same value, bit for bit.
    assert_eq!(t.sample([2.25, 0.5]), t.sample([0.25, 0.5]));
    assert_eq!(t.sample([-0.875, 0.5]), t.sample([0.125, 0.5]));
}

/// Coordinates far outside the texture wrap as `rem_euclid` wraps them, for power-of-two sizes
/// (a mask) and others (a division) alike, below zero too.
#[test]
fn far_coordinates_wrap_by_whole_periods_at_any_size() {
    for (w, h) in [(4, 2), (3, 5), (8, 1)] {
        let t = ramp(w, h);
        // Dyadic coordinates, so that whole periods away they are exact too.
        for (u, v) in [(0.375f32, 0.625f32), (0.0625, 0.9375), (0.875, 0.125)] {
            let inside = t.sample([u, v]);
            for k in [-37.0f32, -6.0, -1.0, 1.0, 5.0, 1000.0] {
                assert_eq!(t.sample([u + k, v]), inside, "{w}x{h} u {u} + {k}");
                assert_eq!(t.sample([u, v + k]), inside, "{w}x{h} v {v} + {k}");
            }
        }
    }
}

#[test]
fn non_finite_coordinates_read_a_finite_value() {
    let t = ramp(3, 3);
    for uv in [
        [f32::NAN, 0.5],
        [f32::INFINITY, 0.5],
        [0.5, f32::NEG_INFINITY],
    ] {
        assert!(t.sample(uv).iter().all(|c| c.is_finite()), "{uv:?}");
    }
}

#[test]
fn a_texture_object_round_trips_and_a_damaged_one_names_its_key() {
    let t = ramp(5, 3);
    let bytes = encode_texture(&t);
    assert_eq!(decode_texture("k", &bytes).unwrap(), t);
    let mut damaged = bytes.clone();
    let last = damaged.len() - 1;
    damaged[last] ^= 1;
    let err = decode_texture("jobs/j/textures/x.tex", &damaged).unwrap_err();
    assert!(err.contains("jobs/j/textures/x.tex"), "{err}");
}

#[test]
fn the_content_key_ignores_the_name_and_sees_every_texel() {
    let a = ramp(4, 4);
    let mut b = a.clone();
    b.name = "other.jpg".into();
    assert_eq!(a.content_key(), b.content_key());
    b.texels[47] ^= 1;
    assert_ne!(a.content_key(), b.content_key());
    assert_eq!(a.content_key().len(), 16);
}

#[test]
fn png_and_jpeg_decode_and_other_bytes_are_refused_with_the_reason() {
    let mut png = Vec::new();
    image::RgbImage::from_fn(3, 2, |x, y| image::Rgb([x as u8 * 100, y as u8 * 200, 9]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let t = decode_texture_image(&png, "a.png").unwrap();
    assert_eq!((t.width, t.height), (3, 2));
    assert_eq!(&t.texels[..6], &[0, 0, 9, 100, 0, 9]);
    assert_eq!(
        decode_texture_image(b"hello", "a.png").unwrap_err(),
        "not a PNG or JPEG image (its first bytes match no image format)"
    );
    let truncated = &png[..png.len() / 2];
    let err = decode_texture_image(truncated, "a.png").unwrap_err();
    assert!(err.starts_with("cannot be decoded as Png: "), "{err}");
}

#[test]
fn an_absurd_size_is_refused_before_it_is_allocated() {
    // A PNG header claiming 100000 x 100000 texels.
    let mut png = Vec::new();
    image::RgbImage::new(1, 1)
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    png[16..20].copy_from_slice(&100_000u32.to_be_bytes());
    png[20..24].copy_from_slice(&100_000u32.to_be_bytes());
    let err = decode_texture_image(&png, "big.png").unwrap_err();
    assert!(
        err == format!(
            "larger than {MAX_TEXTURE_SIDE}x{MAX_TEXTURE_SIDE} texels, the largest texture accepted"
        ) || err.starts_with("cannot be decoded as Png"),
        "{err}"
    );
}

/// Found by fuzzing (target `shuffle_block`): a header whose sides multiply past u64 panicked
/// while its length was checked. It is an error naming the key.
#[test]
fn a_header_with_absurd_sides_is_an_error_not_a_panic() {
    let mut raw = Vec::new();
    raw.extend_from_slice(&u32::MAX.to_le_bytes());
    raw.extend_from_slice(&u32::MAX.to_le_bytes());
    raw.extend_from_slice(&0u32.to_le_bytes());
    raw.extend_from_slice(&[1, 2, 3]);
    let block = crate::shuffle::encode_block(crate::shuffle::RecordKind::Texture, 1, &raw);
    assert_eq!(
        decode_texture("t", &block).unwrap_err(),
        "texture object t: 4294967295x4294967295 texels need 55340232195358851075 bytes, it holds 3"
    );
}

/// A texture path that is a folder or a device is refused before anything is read.
#[test]
fn only_regular_files_are_read() {
    let dir = crate::scratch::Scratch::new("hort-texture-");
    assert_eq!(
        decode_texture_file(&dir, "d").unwrap_err(),
        "not a regular file"
    );
    assert_eq!(
        decode_texture_file(std::path::Path::new("/dev/zero"), "z").unwrap_err(),
        "not a regular file"
    );
    assert_eq!(
        decode_texture_file(&dir.join("gone.png"), "g").unwrap_err(),
        "the file does not exist"
    );
}

/// Sixteen lookups in lanes are the single lookups bit for bit, over the decoded texels (small
/// textures) and through the table (a texture of more than `linear::MAX_TEXELS`): coordinates
/// inside, on texel centres and edges, far outside on both sides, and non-finite; every cell of
/// the small textures (the last column and row wrap to the first), at fractions across it;
/// power-of-two sizes and others, down to one texel; and the reflectance at barycentrics, as
/// `kd_at` gives it.
#[test]
fn lookups_in_lanes_are_the_single_lookups() {
    let mut coordinates: Vec<f32> = vec![0.0, 0.5, 1.0, -0.25, 1e9, -1e9, -37.3];
    coordinates.extend([f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.999_999_9]);
    // A fixed scatter of the rest (a Weyl sequence over [-3, 4)).
    coordinates.extend((0..53).map(|i| (i as f32 * 0.618_034).fract() * 7.0 - 3.0));
    let uv: Vec<[f32; 2]> = (0..coordinates.len())
        .map(|i| [coordinates[i], coordinates[(i * 7 + 3) % coordinates.len()]])
        .collect();
    let sizes = [
        (4, 2),
        (3, 5),
        (8, 1),
        (1, 1),
        (256, 64),
        (255, 37),
        (2049, 512),
    ];
    for (w, h) in sizes {
        let t = ramp(w, h);
        let small = u64::from(w * h) <= linear::MAX_TEXELS;
        assert_eq!(t.linear_texels().is_some(), small, "{w}x{h}");
        let decoded = if small { 16 * u64::from(w * h) } else { 0 };
        assert_eq!(t.memory_bytes(), 3 * u64::from(w * h) + decoded);
        // Every cell of a small texture, at a fraction across it.
        let cells = if small { w * h } else { 0 };
        let mut all = uv.clone();
        all.extend((0..cells).map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let f = (i as f32 * 0.618_034).fract() * 0.9;
            [(x + 0.5 + f) / w as f32, 1.0 - (y + 0.5 + f) / h as f32]
        }));
        all.resize(all.len().next_multiple_of(16), [0.25, 0.75]);
        for lanes in all.chunks_exact(16) {
            let u: [f32; 16] = std::array::from_fn(|k| lanes[k][0]);
            let v: [f32; 16] = std::array::from_fn(|k| lanes[k][1]);
            let got = t.sample_lanes(u, v);
            for (k, uv) in lanes.iter().enumerate() {
                let expected = t.sample(*uv).map(f32::to_bits);
                let got = [got[0][k], got[1][k], got[2][k]].map(f32::to_bits);
                assert_eq!(got, expected, "{w}x{h} at {uv:?}");
            }
        }
        let corners = TexturedCorners {
            texture: 0,
            uv: [[0.1, 0.9], [-2.5, 0.25], [3.0, 7.5]],
        };
        let kd = [0.25, 0.5, 0.9];
        let b: [[f32; 16]; 3] =
            [0, 1, 2].map(|c| std::array::from_fn(|k| ((k * 3 + c) as f32 * 0.381_966).fract()));
        let got = corners.kd_lanes(kd, &t, &b);
        for k in 0..16 {
            let expected = corners.kd_at(kd, &t, [b[0][k], b[1][k], b[2][k]]);
            let got = [got[0][k], got[1][k], got[2][k]];
            assert_eq!(
                got.map(f32::to_bits),
                expected.map(f32::to_bits),
                "{w}x{h} lane {k}"
            );
        }
    }
}
