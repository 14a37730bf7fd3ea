//! `floor.csv`, the reference's own error that `eval/mitsuba_refs.py` estimates from the two
//! halves of its samples: no measured RMSE can fall much below it.

/// The exact header line the file must start with.
pub const HEADER: &str = "scene,rmse,psnr";

/// The (scene, RMSE) rows of the file's text; `path` only names the file in errors, which say
/// `path:line: what`.
pub fn parse(path: &str, text: &str) -> Result<Vec<(String, f64)>, String> {
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim_end() == HEADER => {}
        Some((_, h)) => {
            return Err(format!(
                "{path}:1: expected the header `{HEADER}`, found `{h}`"
            ));
        }
        None => {
            return Err(format!(
                "{path}: empty file, expected the header `{HEADER}`"
            ));
        }
    }
    let mut rows = Vec::new();
    for (i, line) in lines {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.trim_end().split(',').collect();
        let [scene, rmse, _psnr] = fields[..] else {
            return Err(format!(
                "{path}:{n}: expected 3 fields, found {}",
                fields.len()
            ));
        };
        let rmse = rmse
            .parse::<f64>()
            .ok()
            .filter(|v| *v > 0.0 && v.is_finite())
            .ok_or_else(|| format!("{path}:{n}: rmse: not a positive number: `{rmse}`"))?;
        rows.push((scene.to_owned(), rmse));
    }
    Ok(rows)
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
