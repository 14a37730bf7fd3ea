//! `floor.csv`, the reference's own error that `eval/mitsuba_refs.py` estimates from the two
//! halves of its samples: no measured RMSE can fall much below it.

use super::csv_rows::rows;

/// The exact header line the file must start with.
pub const HEADER: &str = "scene,rmse,psnr";

/// The (scene, RMSE) rows of the file's text; `path` only names the file in errors, which say
/// `path:line: what`.
pub fn parse(path: &str, text: &str) -> Result<Vec<(String, f64)>, String> {
    rows(path, text, HEADER, 3)?
        .map(|row| {
            let (n, fields) = row?;
            let (scene, rmse) = (fields[0], fields[1]);
            let rmse = rmse
                .parse::<f64>()
                .ok()
                .filter(|v| *v > 0.0 && v.is_finite())
                .ok_or_else(|| format!("{path}:{n}: rmse: not a positive number: `{rmse}`"))?;
            Ok((scene.to_owned(), rmse))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_and_errors() {
        assert_eq!(
            parse("f.csv", "scene,rmse,psnr\nbunny,6.0e-05,84.4\n").unwrap(),
            vec![("bunny".to_owned(), 6.0e-5)]
        );
        assert_eq!(
            parse("f.csv", "scene,rmse\n").unwrap_err(),
            "f.csv:1: expected the header `scene,rmse,psnr`, found `scene,rmse`"
        );
        assert_eq!(
            parse("f.csv", "scene,rmse,psnr\nbunny,0,1\n").unwrap_err(),
            "f.csv:2: rmse: not a positive number: `0`"
        );
        assert_eq!(
            parse("f.csv", "scene,rmse,psnr\nbunny\n").unwrap_err(),
            "f.csv:2: expected 3 fields, found 1"
        );
    }
}
