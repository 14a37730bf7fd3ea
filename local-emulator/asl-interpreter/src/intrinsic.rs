//! Intrinsic functions of Amazon States Language. The emulator supports the two the HORT
//! definition uses: `States.Format` (the Fail causes) and `States.MathAdd` (the rerun round
//! counters); any other name is a load error.

use serde_json::Value;

use super::paths::Path;

/// An intrinsic function call. The emulator supports `States.Format` and `States.MathAdd` (the
/// ones the HORT definition uses); any other name is a load error.
#[derive(Debug, Clone, PartialEq)]
pub struct Intrinsic {
    /// The function name, e.g. `States.Format`.
    pub name: String,
    /// The arguments, in order.
    pub args: Vec<Arg>,
}

/// One argument of an intrinsic function.
#[derive(Debug, Clone, PartialEq)]
pub enum Arg {
    /// A literal: string (`'…'`), number, `true`, `false` or `null`.
    Literal(Value),
    /// A path into the input or the context.
    Path(Path),
    /// A nested call.
    Call(Intrinsic),
}

const SUPPORTED_INTRINSICS: [&str; 2] = ["States.Format", "States.MathAdd"];

impl Intrinsic {
    /// Parses `States.Name(arg, …)`; the whole text must be one call.
    pub fn parse(text: &str) -> Result<Intrinsic, String> {
        let mut parser = CallParser {
            text,
            at: 0,
            bytes: text.as_bytes(),
        };
        let call = parser.call()?;
        parser.skip_spaces();
        if parser.at != text.len() {
            return Err(format!(
                "unexpected text after the intrinsic call in {text:?} at byte {}",
                parser.at
            ));
        }
        Ok(call)
    }

    /// Evaluates the call: path arguments against `input` (`$…`) or `context` (`$$…`),
    /// nested calls first; a failing path or an unusable argument is the error message.
    pub fn eval(&self, input: &Value, context: &Value) -> Result<Value, String> {
        let args = self
            .args
            .iter()
            .map(|arg| match arg {
                Arg::Literal(v) => Ok(v.clone()),
                Arg::Path(p) => p.resolve(input, context),
                Arg::Call(c) => c.eval(input, context),
            })
            .collect::<Result<Vec<_>, _>>()?;
        match self.name.as_str() {
            "States.Format" => format_call(&args),
            "States.MathAdd" => math_add(&args),
            other => Err(format!("intrinsic function {other} is not supported")),
        }
    }
}

/// `States.MathAdd(a, b)`: the sum of two integers (Step Functions accepts integers between
/// -2147483648 and 2147483647 and so does this).
fn math_add(args: &[Value]) -> Result<Value, String> {
    let int = |v: &Value| v.as_i64().filter(|n| i32::try_from(*n).is_ok());
    match args {
        [a, b] => match (int(a), int(b)) {
            (Some(a), Some(b)) => Ok(Value::from(a + b)),
            _ => Err(format!(
                "States.MathAdd needs two integers between -2147483648 and 2147483647, got {a}                  and {b}"
            )),
        },
        _ => Err(format!(
            "States.MathAdd takes 2 arguments, {} given",
            args.len()
        )),
    }
}

/// `States.Format(template, values…)`: each `{}` takes the next value; strings are inserted
/// without quotes, numbers, booleans and null as JSON; objects and arrays are an error.
fn format_call(args: &[Value]) -> Result<Value, String> {
    let Some(Value::String(template)) = args.first() else {
        return Err("States.Format needs a string template as its first argument".into());
    };
    let values = &args[1..];
    let mut out = String::with_capacity(template.len());
    let mut next = values.iter();
    let mut used = 0;
    let mut chars = template.chars().peekable();
    while let Some(c) = chars.next() {
        if c == ESCAPED_BRACE {
            out.extend(chars.next());
        } else if c == '{' && chars.peek() == Some(&'}') {
            chars.next();
            let value = next.next().ok_or_else(|| {
                format!(
                    "States.Format: the template has more '{{}}' than the {} value(s) given",
                    values.len()
                )
            })?;
            used += 1;
            match value {
                Value::String(s) => out.extend(s.chars().filter(|&c| c != ESCAPED_BRACE)),
                Value::Number(_) | Value::Bool(_) | Value::Null => out.push_str(&value.to_string()),
                _ => return Err("States.Format: objects and arrays cannot be formatted".into()),
            }
        } else {
            out.push(c);
        }
    }
    if used != values.len() {
        return Err(format!(
            "States.Format: {} value(s) given for {used} '{{}}'",
            values.len()
        ));
    }
    Ok(Value::String(out))
}

struct CallParser<'t> {
    text: &'t str,
    bytes: &'t [u8],
    at: usize,
}

impl CallParser<'_> {
    fn skip_spaces(&mut self) {
        while self.bytes.get(self.at).is_some_and(u8::is_ascii_whitespace) {
            self.at += 1;
        }
    }

    fn error<T>(&self, what: &str) -> Result<T, String> {
        Err(format!("{what} in {:?} at byte {}", self.text, self.at))
    }

    fn call(&mut self) -> Result<Intrinsic, String> {
        self.skip_spaces();
        let start = self.at;
        while self
            .bytes
            .get(self.at)
            .is_some_and(|b| b.is_ascii_alphanumeric() || *b == b'.')
        {
            self.at += 1;
        }
        let name = self.text[start..self.at].to_owned();
        if !SUPPORTED_INTRINSICS.contains(&name.as_str()) {
            return Err(format!(
                "intrinsic function {name:?} is not supported by the emulator (supported: {})",
                SUPPORTED_INTRINSICS.join(", ")
            ));
        }
        if self.bytes.get(self.at) != Some(&b'(') {
            return self.error("expected '(' after the function name");
        }
        self.at += 1;
        let mut args = Vec::new();
        self.skip_spaces();
        if self.bytes.get(self.at) == Some(&b')') {
            self.at += 1;
            return Ok(Intrinsic { name, args });
        }
        loop {
            args.push(self.arg()?);
            self.skip_spaces();
            match self.bytes.get(self.at) {
                Some(b',') => self.at += 1,
                Some(b')') => {
                    self.at += 1;
                    return Ok(Intrinsic { name, args });
                }
                _ => return self.error("expected ',' or ')'"),
            }
        }
    }

    fn arg(&mut self) -> Result<Arg, String> {
        self.skip_spaces();
        match self.bytes.get(self.at) {
            Some(b'\'') => self.string().map(|s| Arg::Literal(Value::String(s))),
            Some(b'$') => {
                let start = self.at;
                while self
                    .bytes
                    .get(self.at)
                    .is_some_and(|b| !matches!(b, b',' | b')') && !b.is_ascii_whitespace())
                {
                    self.at += 1;
                }
                Path::parse(&self.text[start..self.at]).map(Arg::Path)
            }
            Some(b'S') => self.call().map(Arg::Call),
            Some(_) => {
                let start = self.at;
                while self
                    .bytes
                    .get(self.at)
                    .is_some_and(|b| !matches!(b, b',' | b')') && !b.is_ascii_whitespace())
                {
                    self.at += 1;
                }
                let word = &self.text[start..self.at];
                match serde_json::from_str::<Value>(word) {
                    Ok(v @ (Value::Number(_) | Value::Bool(_) | Value::Null)) => {
                        Ok(Arg::Literal(v))
                    }
                    _ => Err(format!(
                        "argument {word:?} in {:?} is not a string, number, boolean, null, \
                         path or call",
                        self.text
                    )),
                }
            }
            None => self.error("unexpected end"),
        }
    }

    /// A `'…'` literal with the escapes `\'`, `\{`, `\}` and `\\`; an escaped brace is stored
    /// after an [`ESCAPED_BRACE`] marker.
    fn string(&mut self) -> Result<String, String> {
        self.at += 1;
        let mut out = String::new();
        let mut chars = self.text[self.at..].char_indices();
        while let Some((i, c)) = chars.next() {
            match c {
                '\'' => {
                    self.at += i + 1;
                    return Ok(out);
                }
                '\\' => match chars.next() {
                    Some((_, e @ ('\'' | '\\'))) => out.push(e),
                    Some((_, e @ ('{' | '}'))) => {
                        out.push(ESCAPED_BRACE);
                        out.push(e);
                    }
                    _ => return self.error("bad escape in a string literal"),
                },
                c => out.push(c),
            }
        }
        self.error("unterminated string literal")
    }
}

/// Marks an escaped brace (`\{`, `\}`) inside a parsed string literal, so that
/// [`format_call`] copies the brace instead of taking `\{}` as a placeholder. It never reaches
/// a result: `format_call` drops it from the template and from the values it inserts.
const ESCAPED_BRACE: char = '\u{0}';

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn math_add_adds_two_integers() {
        let eval =
            |text: &str, input: Value| Intrinsic::parse(text).unwrap().eval(&input, &json!({}));
        assert_eq!(
            eval("States.MathAdd($.n, 1)", json!({"n": 2})),
            Ok(json!(3))
        );
        assert_eq!(
            eval("States.MathAdd(-1, $.n)", json!({"n": 0})),
            Ok(json!(-1))
        );
        assert!(eval("States.MathAdd($.n, 1)", json!({"n": "2"})).is_err());
        assert!(eval("States.MathAdd(1.5, 1)", json!({})).is_err());
        assert!(eval("States.MathAdd(1)", json!({})).is_err());
    }

    #[test]
    fn format_handles_types_escapes_and_count_errors() {
        let eval = |text: &str, input: Value| {
            Intrinsic::parse(text)
                .map_err(|e| e.to_string())
                .and_then(|c| c.eval(&input, &Value::Null))
        };
        assert_eq!(
            eval(
                "States.Format('{} {} {} {}', $.s, $.n, $.b, $.z)",
                json!({"s": "x", "n": 1.5, "b": true, "z": null})
            ),
            Ok(json!("x 1.5 true null"))
        );
        assert_eq!(
            eval(r"States.Format('a \{} \'q\' \\ {}', 2)", json!({})),
            Ok(json!(r"a {} 'q' \ 2"))
        );
        assert_eq!(
            eval(
                "States.Format('{}', States.Format('<{}>', 'in'))",
                json!({})
            ),
            Ok(json!("<in>"))
        );
        assert!(
            eval("States.Format('{} {}', 1)", json!({}))
                .unwrap_err()
                .contains("more")
        );
        assert!(
            eval("States.Format('x', 1)", json!({}))
                .unwrap_err()
                .contains("given")
        );
        assert!(eval("States.Format('{}', $.o)", json!({"o": {}})).is_err());
        let err = Intrinsic::parse("States.JsonMerge($.a, $.b, false)").unwrap_err();
        assert!(
            err.contains("States.JsonMerge") && err.contains("not supported"),
            "{err}"
        );
        assert!(Intrinsic::parse("States.Format('x') trailing").is_err());
        assert!(Intrinsic::parse("States.Format('x'").is_err());
    }
}
