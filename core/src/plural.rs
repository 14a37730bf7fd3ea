//! Counts in messages: "1 split", "2 splits", never "1 splits".

/// The plural of `noun`: `vertex` -> `vertices`, anything else with an `s`.
pub fn plural(noun: &str) -> String {
    match noun {
        "vertex" => "vertices".into(),
        other => format!("{other}s"),
    }
}

/// `n` and `noun`, singular for exactly one: `count(1, "split")` is `1 split`, `count(2,
/// "split")` is `2 splits`, `count(0, "vertex")` is `0 vertices`. Every message that counts
/// things says it this way.
pub fn count(n: u64, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {}", plural(noun))
    }
}

/// [`count`] with its verb: `1 vertex is`, `2 vertices are`.
pub fn count_is(n: u64, noun: &str) -> String {
    format!("{} {}", count(n, noun), if n == 1 { "is" } else { "are" })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_is_singular_everything_else_plural() {
        assert_eq!(count(1, "split"), "1 split");
        assert_eq!(count(2, "split"), "2 splits");
        assert_eq!(count(0, "triangle"), "0 triangles");
        assert_eq!(count(1, "vertex"), "1 vertex");
        assert_eq!(count(2, "vertex"), "2 vertices");
        assert_eq!(count(1, "finished task"), "1 finished task");
        assert_eq!(count(1_000, "span"), "1000 spans");
        assert_eq!(count_is(1, "vertex"), "1 vertex is");
        assert_eq!(count_is(0, "normal"), "0 normals are");
    }
}
