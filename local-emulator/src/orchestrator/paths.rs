//! The JSONPath subset of Amazon States Language: reference paths (`$`, `$.a.b`, `$.a[0]`,
//! `$['a b']`, and `$$.…` into the context object), `ResultPath` targets, payload templates
//! (`Parameters`, `ItemSelector`, `ResultSelector`, whose `.$` keys take a path or an intrinsic
//! function), and the intrinsic function `States.Format`.
//!
//! Everything is parsed once when the definition loads, so a malformed path is a load error
//! naming the state and field; evaluation errors (a path that selects nothing) are runtime
//! errors, which the interpreter reports as `States.Runtime`, as Step Functions does.

use serde_json::{Map, Value};

/// One step of a path: an object field or an array index.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Step {
    /// `.name` or `['name']`.
    Field(String),
    /// `[n]`.
    Index(usize),
}

/// A reference path: `$` (the state's input) or `$$` (the context object) followed by steps.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Path {
    /// True for `$$…` (the context object), false for `$…` (the input).
    pub context: bool,
    /// The steps after the root, in order.
    pub steps: Vec<Step>,
    /// The path as written, for messages.
    pub text: String,
}

impl Path {
    /// Parses a reference path. Filters, wildcards, slices and recursive descent are rejected
    /// with a message naming the construct.
    pub fn parse(text: &str) -> Result<Path, String> {
        let (context, rest) = if let Some(rest) = text.strip_prefix("$$") {
            (true, rest)
        } else if let Some(rest) = text.strip_prefix('$') {
            (false, rest)
        } else {
            return Err(format!("path {text:?} must start with '$' or '$$'"));
        };
        let bad = |what: &str| {
            Err(format!(
                "path {text:?}: {what} is not supported by the emulator (supported: $, $$, \
                 .field, ['field'], [index])"
            ))
        };
        let mut steps = Vec::new();
        let mut chars = rest.char_indices().peekable();
        while let Some((at, c)) = chars.next() {
            match c {
                '.' => {
                    if rest[at + 1..].starts_with('.') {
                        return bad("recursive descent '..'");
                    }
                    let start = at + 1;
                    let mut end = rest.len();
                    while let Some(&(i, c)) = chars.peek() {
                        if c == '.' || c == '[' {
                            end = i;
                            break;
                        }
                        chars.next();
                    }
                    let name = &rest[start..end];
                    if name.is_empty() {
                        return Err(format!("path {text:?}: empty field name after '.'"));
                    }
                    if name == "*" {
                        return bad("wildcard '*'");
                    }
                    steps.push(Step::Field(name.to_owned()));
                }
                '[' => {
                    let close = rest[at..]
                        .find(']')
                        .map(|i| at + i)
                        .ok_or_else(|| format!("path {text:?}: '[' without ']'"))?;
                    let inner = &rest[at + 1..close];
                    if let Some(name) = inner
                        .strip_prefix('\'')
                        .and_then(|s| s.strip_suffix('\''))
                    {
                        steps.push(Step::Field(name.to_owned()));
                    } else if !inner.is_empty() && inner.bytes().all(|b| b.is_ascii_digit()) {
                        let index = inner
                            .parse()
                            .map_err(|_| format!("path {text:?}: index {inner} is too large"))?;
                        steps.push(Step::Index(index));
                    } else {
                        return bad(&format!("selector [{inner}]"));
                    }
                    while chars.peek().is_some_and(|&(i, _)| i <= close) {
                        chars.next();
                    }
                }
                other => {
                    return Err(format!(
                        "path {text:?}: unexpected character {other:?} (expected '.' or '[')"
                    ));
                }
            }
        }
        Ok(Path {
            context,
            steps,
            text: text.to_owned(),
        })
    }

    /// The selected value, or `None` if a step finds no such field or index.
    pub fn select<'v>(&self, input: &'v Value, context: &'v Value) -> Option<&'v Value> {
        let mut at = if self.context { context } else { input };
        for step in &self.steps {
            at = match step {
                Step::Field(name) => at.as_object()?.get(name)?,
                Step::Index(i) => at.as_array()?.get(*i)?,
            };
        }
        Some(at)
    }

    /// Like [`Path::select`], but a miss is an error naming the path.
    pub fn resolve(&self, input: &Value, context: &Value) -> Result<Value, String> {
        self.select(input, context)
            .cloned()
            .ok_or_else(|| format!("the path {:?} selects nothing", self.text))
    }
}

/// Where a state puts its result (`ResultPath`) within its raw input.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ResultPath {
    /// `"$"` (the default): the result replaces the input.
    Replace,
    /// `null`: the result is discarded and the input passes through.
    Discard,
    /// `"$.a.b"`: the result is stored at that field, creating objects on the way.
    Field(Vec<String>, String),
}

impl ResultPath {
    /// Parses a `ResultPath` value (`None` for JSON null). Only `$` and field steps are allowed.
    pub fn parse(text: Option<&str>) -> Result<ResultPath, String> {
        let Some(text) = text else {
            return Ok(ResultPath::Discard);
        };
        let path = Path::parse(text)?;
        if path.context {
            return Err(format!("ResultPath {text:?} cannot point into the context '$$'"));
        }
        let mut fields = Vec::with_capacity(path.steps.len());
        for step in path.steps {
            match step {
                Step::Field(name) => fields.push(name),
                Step::Index(_) => {
                    return Err(format!("ResultPath {text:?}: array indices are not allowed"));
                }
            }
        }
        Ok(if fields.is_empty() {
            ResultPath::Replace
        } else {
            ResultPath::Field(fields, text.to_owned())
        })
    }

    /// Combines the state's raw input with its result. Storing under a field of a non-object
    /// is an error naming the path, as in Step Functions.
    pub fn apply(&self, input: Value, result: Value) -> Result<Value, String> {
        match self {
            ResultPath::Replace => Ok(result),
            ResultPath::Discard => Ok(input),
            ResultPath::Field(fields, text) => {
                let mut root = input;
                let mut at = &mut root;
                for (i, name) in fields.iter().enumerate() {
                    let Some(object) = at.as_object_mut() else {
                        return Err(format!(
                            "ResultPath {text:?}: cannot store a field in a non-object value"
                        ));
                    };
                    if i + 1 == fields.len() {
                        object.insert(name.clone(), result);
                        break;
                    }
                    at = object
                        .entry(name.clone())
                        .or_insert_with(|| Value::Object(Map::new()));
                }
                Ok(root)
            }
        }
    }
}

/// A payload template: JSON whose `.$` keys are evaluated against the input and context.
#[derive(Debug, Clone, PartialEq)]
pub enum Template {
    /// A value copied as is.
    Literal(Value),
    /// An object whose fields are templates (keys already stripped of `.$`).
    Object(Vec<(String, Template)>),
    /// An array whose elements are templates.
    Array(Vec<Template>),
    /// The value a path selects (from a `.$` key).
    Path(Path),
    /// The value an intrinsic function returns (from a `.$` key).
    Call(Intrinsic),
}

impl Template {
    /// Compiles a template; a bad `.$` value is an error naming the key.
    pub fn compile(value: &Value) -> Result<Template, String> {
        match value {
            Value::Object(fields) => {
                let mut out = Vec::with_capacity(fields.len());
                for (key, value) in fields {
                    match key.strip_suffix(".$") {
                        Some(name) => {
                            let Some(text) = value.as_str() else {
                                return Err(format!("field {key:?} must hold a string"));
                            };
                            out.push((name.to_owned(), Template::expression(text, key)?));
                        }
                        None => out.push((key.clone(), Template::compile(value)?)),
                    }
                }
                Ok(Template::Object(out))
            }
            Value::Array(items) => items
                .iter()
                .map(Template::compile)
                .collect::<Result<_, _>>()
                .map(Template::Array),
            other => Ok(Template::Literal(other.clone())),
        }
    }

    /// A path or an intrinsic call, as allowed in a `.$` field, `ErrorPath` or `CausePath`.
    pub fn expression(text: &str, field: &str) -> Result<Template, String> {
        if text.starts_with('$') {
            Path::parse(text)
                .map(Template::Path)
                .map_err(|e| format!("field {field:?}: {e}"))
        } else if text.starts_with("States.") {
            Intrinsic::parse(text)
                .map(Template::Call)
                .map_err(|e| format!("field {field:?}: {e}"))
        } else {
            Err(format!(
                "field {field:?}: {text:?} is neither a path ('$…') nor an intrinsic function \
                 ('States.…')"
            ))
        }
    }

    /// Evaluates the template against the effective input and the context object.
    pub fn eval(&self, input: &Value, context: &Value) -> Result<Value, String> {
        match self {
            Template::Literal(v) => Ok(v.clone()),
            Template::Object(fields) => {
                let mut out = Map::new();
                for (key, template) in fields {
                    out.insert(key.clone(), template.eval(input, context)?);
                }
                Ok(Value::Object(out))
            }
            Template::Array(items) => items
                .iter()
                .map(|t| t.eval(input, context))
                .collect::<Result<_, _>>()
                .map(Value::Array),
            Template::Path(path) => path.resolve(input, context),
            Template::Call(call) => call.eval(input, context),
        }
    }
}

/// An intrinsic function call. The emulator supports `States.Format` only (the one the HORT
/// definition uses); any other name is a load error.
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

const SUPPORTED_INTRINSICS: [&str; 1] = ["States.Format"];

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

    fn eval(&self, input: &Value, context: &Value) -> Result<Value, String> {
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
            other => Err(format!("intrinsic function {other} is not supported")),
        }
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
    fn paths_select_fields_indices_and_context() {
        let input = json!({"a": {"b": [10, {"c": "x"}]}, "odd key": 1});
        let ctx = json!({"State": {"RetryCount": 2}});
        let sel = |p: &str| Path::parse(p).unwrap().select(&input, &ctx).cloned();
        assert_eq!(sel("$"), Some(input.clone()));
        assert_eq!(sel("$.a.b[0]"), Some(json!(10)));
        assert_eq!(sel("$.a.b[1].c"), Some(json!("x")));
        assert_eq!(sel("$['odd key']"), Some(json!(1)));
        assert_eq!(sel("$$.State.RetryCount"), Some(json!(2)));
        assert_eq!(sel("$.a.missing"), None);
        assert_eq!(sel("$.a.b[5]"), None);
        let err = Path::parse("$.a")
            .unwrap()
            .resolve(&json!(1), &ctx)
            .unwrap_err();
        assert!(err.contains("\"$.a\""), "{err}");
    }

    #[test]
    fn unsupported_path_syntax_is_named() {
        for (bad, what) in [
            ("$..a", "recursive descent"),
            ("$.a[*]", "[*]"),
            ("$.a[?(@.x)]", "[?(@.x)]"),
            ("$.*", "wildcard"),
            ("a.b", "must start"),
            ("$.a[", "without ']'"),
            ("$.", "empty field"),
        ] {
            let err = Path::parse(bad).unwrap_err();
            assert!(err.contains(what), "{bad}: {err}");
        }
    }

    #[test]
    fn result_path_replaces_discards_and_nests() {
        let input = json!({"job": "j"});
        let set = |p: Option<&str>| {
            ResultPath::parse(p)
                .unwrap()
                .apply(input.clone(), json!(7))
                .unwrap()
        };
        assert_eq!(set(Some("$")), json!(7));
        assert_eq!(set(None), input);
        assert_eq!(set(Some("$.plan.x")), json!({"job": "j", "plan": {"x": 7}}));
        assert!(ResultPath::parse(Some("$.a[0]")).is_err());
        assert!(ResultPath::parse(Some("$$.a")).is_err());
        let err = ResultPath::parse(Some("$.a"))
            .unwrap()
            .apply(json!([1]), json!(1))
            .unwrap_err();
        assert!(err.contains("non-object"), "{err}");
    }

    #[test]
    fn templates_evaluate_paths_calls_and_literals() {
        let t = Template::compile(&json!({
            "FunctionName": "${WorkerFunctionArn}",
            "Payload": {
                "job.$": "$.job",
                "attempt.$": "$$.State.RetryCount",
                "list": [{"k.$": "$.job"}, 3],
                "key.$": "States.Format('jobs/{}/items/{}.json', $.job, 'cast-map')"
            }
        }))
        .unwrap();
        let out = t
            .eval(&json!({"job": "j1"}), &json!({"State": {"RetryCount": 1}}))
            .unwrap();
        assert_eq!(
            out,
            json!({
                "FunctionName": "${WorkerFunctionArn}",
                "Payload": {
                    "job": "j1", "attempt": 1, "list": [{"k": "j1"}, 3],
                    "key": "jobs/j1/items/cast-map.json"
                }
            })
        );
        let err = Template::compile(&json!({"a.$": "job"})).unwrap_err();
        assert!(err.contains("\"a.$\""), "{err}");
        let err = Template::compile(&json!({"a.$": 3})).unwrap_err();
        assert!(err.contains("\"a.$\""), "{err}");
    }

    #[test]
    fn format_handles_types_escapes_and_count_errors() {
        let eval = |text: &str, input: Value| {
            Intrinsic::parse(text)
                .map_err(|e| e.to_string())
                .and_then(|c| c.eval(&input, &Value::Null))
        };
        assert_eq!(
            eval("States.Format('{} {} {} {}', $.s, $.n, $.b, $.z)", json!({"s": "x", "n": 1.5, "b": true, "z": null})),
            Ok(json!("x 1.5 true null"))
        );
        assert_eq!(
            eval(r"States.Format('a \{} \'q\' \\ {}', 2)", json!({})),
            Ok(json!(r"a {} 'q' \ 2"))
        );
        assert_eq!(
            eval("States.Format('{}', States.Format('<{}>', 'in'))", json!({})),
            Ok(json!("<in>"))
        );
        assert!(eval("States.Format('{} {}', 1)", json!({})).unwrap_err().contains("more"));
        assert!(eval("States.Format('x', 1)", json!({})).unwrap_err().contains("given"));
        assert!(eval("States.Format('{}', $.o)", json!({"o": {}})).is_err());
        let err = Intrinsic::parse("States.JsonMerge($.a, $.b, false)").unwrap_err();
        assert!(err.contains("States.JsonMerge") && err.contains("not supported"), "{err}");
        assert!(Intrinsic::parse("States.Format('x') trailing").is_err());
        assert!(Intrinsic::parse("States.Format('x'").is_err());
    }
}
