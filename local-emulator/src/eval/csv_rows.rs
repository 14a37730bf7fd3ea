//! The reading both result files of `eval/mitsuba_refs.py` share: an exact header line, then
//! rows of comma-separated fields (blank lines skipped), every error `path:line: what`.

/// The data rows of `text` (a file named `path` in errors), in order, as (1-based line number,
/// fields), once its first line is checked to be exactly `header`; a row without exactly
/// `fields` fields is an error in its place, so rows before it are read first.
pub fn rows<'t>(
    path: &'t str,
    text: &'t str,
    header: &str,
    fields: usize,
) -> Result<impl Iterator<Item = Result<(usize, Vec<&'t str>), String>> + 't, String> {
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim_end() == header => {}
        Some((_, h)) => {
            return Err(format!(
                "{path}:1: expected the header `{header}`, found `{h}`"
            ));
        }
        None => {
            return Err(format!(
                "{path}: empty file, expected the header `{header}`"
            ));
        }
    }
    Ok(lines
        .filter(|(_, line)| !line.trim().is_empty())
        .map(move |(i, line)| {
            let row: Vec<&str> = line.trim_end().split(',').collect();
            if row.len() != fields {
                return Err(format!(
                    "{path}:{}: expected {fields} fields, found {}",
                    i + 1,
                    row.len()
                ));
            }
            Ok((i + 1, row))
        }))
}
