//! `mitsuba.csv`, the timed Mitsuba sweep `eval/mitsuba_refs.py` writes: one row per scene,
//! sampler and sample count, with the render time on one thread and the errors against the
//! reference.

use super::Point;
use super::csv_rows::rows;

/// The exact header line the file must start with.
pub const HEADER: &str = "scene,sampler,spp,seconds,rmse,relmse,psnr";

/// Parses the file's text; `path` only names the file in errors, which say `path:line: what`.
/// Each row becomes a [`Point`] of method `mitsuba {sampler}`.
pub fn parse(path: &str, text: &str) -> Result<Vec<Point>, String> {
    let mut points = Vec::new();
    for row in rows(path, text, HEADER, 7)? {
        let (n, fields) = row?;
        let number = |col: usize, name: &str| -> Result<f64, String> {
            fields[col]
                .parse::<f64>()
                .map_err(|_| format!("{path}:{n}: {name}: not a number: `{}`", fields[col]))
        };
        let spp: u32 =
            fields[2].parse().ok().filter(|&s| s > 0).ok_or_else(|| {
                format!("{path}:{n}: spp: not a positive integer: `{}`", fields[2])
            })?;
        let seconds = number(3, "seconds")?;
        if !(seconds > 0.0 && seconds.is_finite()) {
            return Err(format!(
                "{path}:{n}: seconds: must be positive and finite, got {seconds}"
            ));
        }
        let (rmse, relmse, psnr) = (number(4, "rmse")?, number(5, "relmse")?, number(6, "psnr")?);
        for (name, v) in [("rmse", rmse), ("relmse", relmse)] {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(format!(
                    "{path}:{n}: {name}: must be non-negative and finite, got {v}"
                ));
            }
        }
        if fields[0].is_empty() || fields[1].is_empty() {
            return Err(format!("{path}:{n}: scene and sampler must not be empty"));
        }
        points.push(Point {
            scene: fields[0].to_owned(),
            method: format!("mitsuba {}", fields[1]),
            spp,
            seconds,
            errors: super::metrics::Errors { rmse, relmse, psnr },
        });
    }
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        parse("m.csv", text).unwrap_err()
    }

    #[test]
    fn rows_become_points() {
        let text = format!("{HEADER}\nbunny,multijitter,64,0.5,0.01,0.002,40.0\n\n");
        let p = parse("m.csv", &text).unwrap();
        assert_eq!(p.len(), 1);
        assert_eq!(
            (p[0].scene.as_str(), p[0].method.as_str(), p[0].spp),
            ("bunny", "mitsuba multijitter", 64)
        );
        assert_eq!(p[0].seconds, 0.5);
        assert_eq!(p[0].errors.rmse, 0.01);
        assert_eq!(p[0].errors.relmse, 0.002);
        assert_eq!(p[0].errors.psnr, 40.0);
    }

    #[test]
    fn bad_files_name_file_line_and_field() {
        assert_eq!(
            err(""),
            "m.csv: empty file, expected the header `scene,sampler,spp,seconds,rmse,relmse,psnr`"
        );
        assert_eq!(
            err("scene,spp\n"),
            "m.csv:1: expected the header `scene,sampler,spp,seconds,rmse,relmse,psnr`, found `scene,spp`"
        );
        let h = HEADER;
        assert_eq!(
            err(&format!("{h}\na,b,1,1,1,1\n")),
            "m.csv:2: expected 7 fields, found 6"
        );
        assert_eq!(
            err(&format!("{h}\na,b,0,1,1,1,1\n")),
            "m.csv:2: spp: not a positive integer: `0`"
        );
        assert_eq!(
            err(&format!("{h}\na,b,4,1,1,1,1\na,b,4,x,1,1,1\n")),
            "m.csv:3: seconds: not a number: `x`"
        );
        assert_eq!(
            err(&format!("{h}\na,b,4,-1,1,1,1\n")),
            "m.csv:2: seconds: must be positive and finite, got -1"
        );
        assert_eq!(
            err(&format!("{h}\na,b,4,1,NaN,1,1\n")),
            "m.csv:2: rmse: must be non-negative and finite, got NaN"
        );
        assert_eq!(
            err(&format!("{h}\n,b,4,1,1,1,1\n")),
            "m.csv:2: scene and sampler must not be empty"
        );
    }
}
