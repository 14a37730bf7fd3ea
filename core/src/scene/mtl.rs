//! What a material library asks for that the renderer does not do. The renderer uses `Kd` and
//! its diffuse map `map_Kd` only (two-sided Lambertian surfaces); other texture maps,
//! highlights, emission and transparency would change the image in another renderer, so each
//! of them is reported, once per kind and file, naming the first material and line and counting
//! the others. So is a `Kd` above 1.

use std::collections::HashMap;
use std::path::Path;

/// The kinds reported, in message order (the discriminant indexes [`KINDS`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Texture,
    Specular,
    Emission,
    Transparency,
    BrightKd,
}

const KINDS: [Kind; 5] = [
    Kind::Texture,
    Kind::Specular,
    Kind::Emission,
    Kind::Transparency,
    Kind::BrightKd,
];

/// The first occurrence of a kind and the materials that show it.
struct Found {
    line: usize,
    material: String,
    /// The statement as written (keyword and values), whitespace collapsed.
    statement: String,
    materials: Vec<String>,
}

/// Warnings for the MTL file at `path` with contents `text`: one per kind found, in the order
/// textures, specular, emission, transparency, Kd above 1.
pub(super) fn mtl_warnings(path: &Path, text: &str) -> Vec<String> {
    let mut found: [Option<Found>; 5] = Default::default();
    let mut material = String::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        if keyword.starts_with('#') {
            continue;
        }
        if keyword == "newmtl" {
            material = line["newmtl".len()..].trim().to_string();
            continue;
        }
        let values: Vec<&str> = words.collect();
        let Some(kind) = classify(keyword, &values) else {
            continue;
        };
        let slot = &mut found[kind as usize];
        let entry = slot.get_or_insert_with(|| Found {
            line: i + 1,
            material: material.clone(),
            statement: std::iter::once(keyword)
                .chain(values.iter().copied())
                .collect::<Vec<_>>()
                .join(" "),
            materials: Vec::new(),
        });
        if !entry.materials.contains(&material) {
            entry.materials.push(material.clone());
        }
    }
    KINDS
        .iter()
        .zip(found)
        .filter_map(|(&kind, f)| f.map(|f| message(path, kind, &f)))
        .collect()
}

/// The file a `map_Kd` statement names, from the text after the keyword: options
/// (`-s 1 1 1 file.png`) come first, so the file is the last word.
pub fn map_file(statement: &str) -> &str {
    statement
        .split_ascii_whitespace()
        .last()
        .unwrap_or(statement)
}

/// The files the `map_Kd` statements of the material library `text` name, relative to the
/// library's folder, each once, in order: what a scene's files include besides its OBJ and
/// MTL files.
pub fn diffuse_map_files(text: &str) -> Vec<String> {
    let mut files: Vec<String> = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if let Some(rest) = line.strip_prefix("map_Kd")
            && rest.starts_with(char::is_whitespace)
        {
            let file = map_file(rest).to_string();
            if !files.contains(&file) {
                files.push(file);
            }
        }
    }
    files
}

/// The 1-based line of each material's `map_Kd` statement (the first, if several).
pub(super) fn diffuse_map_lines(text: &str) -> HashMap<String, usize> {
    let mut lines = HashMap::new();
    let mut material = String::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        match line.split_whitespace().next() {
            Some("newmtl") => material = line["newmtl".len()..].trim().to_string(),
            Some("map_Kd") => {
                lines.entry(material.clone()).or_insert(i + 1);
            }
            _ => {}
        }
    }
    lines
}

/// Colour statements, which `tobj` reads as exactly three numbers.
const COLOURS: [&str; 4] = ["Ka", "Kd", "Ks", "Ke"];

/// The library text as `tobj` can read it: a colour statement (`Ka`, `Kd`, `Ks`, `Ke`) with one
/// value is written out with three (the MTL rule: g and b default to r); one with no or two
/// values is an error, returned as (1-based line, statement), since `tobj` 4.0.5 panics on it.
/// Every other line is kept as it is, so line numbers do not change.
pub(super) fn with_full_colours(text: &str) -> Result<String, (usize, String)> {
    let mut out = String::with_capacity(text.len() + 16);
    for (i, line) in text.lines().enumerate() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words[..] {
            [keyword, ref values @ ..] if COLOURS.contains(&keyword) && values.len() < 3 => {
                let [grey] = values else {
                    return Err((i + 1, words.join(" ").chars().take(60).collect()));
                };
                out.push_str(&format!("{keyword} {grey} {grey} {grey}"));
            }
            _ => out.push_str(line),
        }
        out.push('\n');
    }
    Ok(out)
}

/// Statements whose values must be numbers (as `tobj` reads them).
const NUMERIC: [&str; 10] = ["Ka", "Kd", "Ks", "Ke", "Tf", "Ns", "Ni", "d", "Tr", "illum"];

/// The first line (1-based) of `text` holding a numeric statement without values or with a value
/// that is not a number, with the statement (whitespace collapsed, at most 60 characters): where
/// a library that `tobj` refused as a whole is wrong. `None` if every such statement parses.
pub(super) fn first_bad_number(text: &str) -> Option<(usize, String)> {
    text.lines().enumerate().find_map(|(i, raw)| {
        let words: Vec<&str> = raw.split_whitespace().collect();
        let (&keyword, values) = words.split_first()?;
        let bad = NUMERIC.contains(&keyword)
            && (values.is_empty() || values.iter().any(|v| v.parse::<f32>().is_err()));
        bad.then(|| (i + 1, words.join(" ").chars().take(60).collect()))
    })
}

/// Which kind a statement shows, if any: texture statements other than `map_Kd` always
/// (`map_Kd` is rendered), colours and factors only
/// when they have a visible effect elsewhere (a nonzero `Ks` or `Ke`, `d` below 1, `Tr` above 0)
/// and `Kd` when a channel exceeds 1.
fn classify(keyword: &str, values: &[&str]) -> Option<Kind> {
    let lower = keyword.to_ascii_lowercase();
    let numbers = || values.iter().filter_map(|v| v.parse::<f32>().ok());
    if keyword == "map_Kd" {
        return None;
    }
    if lower.starts_with("map_") || matches!(lower.as_str(), "bump" | "disp" | "decal" | "refl") {
        return Some(Kind::Texture);
    }
    match keyword {
        "Ks" if numbers().any(|v| v > 0.0) => Some(Kind::Specular),
        "Ke" if numbers().any(|v| v > 0.0) => Some(Kind::Emission),
        "d" if numbers().any(|v| v < 1.0) => Some(Kind::Transparency),
        "Tr" if numbers().any(|v| v > 0.0) => Some(Kind::Transparency),
        "Kd" if numbers().any(|v| v > 1.0) => Some(Kind::BrightKd),
        _ => None,
    }
}

fn message(path: &Path, kind: Kind, f: &Found) -> String {
    let name = if f.material.is_empty() {
        "(before any newmtl)".to_string()
    } else {
        format!("{:?}", f.material)
    };
    let more = match f.materials.len() - 1 {
        0 => String::new(),
        1 => " (and 1 more material)".to_string(),
        n => format!(" (and {n} more materials)"),
    };
    let what = match kind {
        Kind::Texture => "uses a texture",
        Kind::Specular => "has a specular colour",
        Kind::Emission => "is emissive",
        Kind::Transparency => "is partly transparent",
        Kind::BrightKd => "has a diffuse colour above 1",
    };
    let instead = match kind {
        Kind::Texture => {
            "only diffuse textures (map_Kd) are rendered; this map is ignored (the surface shows \
             its Kd colour and map_Kd, if any)"
        }
        Kind::Specular => {
            "highlights and reflections are not rendered, the surface is purely diffuse (Kd only)"
        }
        Kind::Emission => {
            "emission is not rendered, the surface neither glows nor lights the scene (give the \
             scene lights in a manifest instead)"
        }
        Kind::Transparency => "transparency is not rendered, the surface is opaque",
        Kind::BrightKd => {
            "a surface that reflects more light than it receives is not physically plausible; \
             it is rendered as given (use Kd values from 0 to 1)"
        }
    };
    format!(
        "{}:{}: material {name} {what} ({}){more}; {instead}",
        path.display(),
        f.line,
        f.statement
    )
}
