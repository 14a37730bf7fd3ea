//! The JSONPath subset of Amazon States Language: reference paths (`$`, `$.a.b`, `$.a[0]`,
//! `$['a b']`, and `$$.…` into the context object), `ResultPath` targets, payload templates
//! (`Parameters`, `ItemSelector`, `ResultSelector`, whose `.$` keys take a path or an intrinsic
//! function, see [`super::intrinsic`]). A template's `.$` path may also use the wildcard `[*]`
//! (as in `$[*].lost`): such a path selects the array of every match, in order, leaving out the
//! elements where the rest of the path finds nothing (an empty array if none), as Step
//! Functions' JSONPath does for indefinite paths. Reference paths (`InputPath`, `ResultPath`,
//! `ItemsPath`, a Choice `Variable`, intrinsic arguments) refuse wildcards, as in Step
//! Functions.
//!
//! Everything is parsed once when the definition loads, so a malformed path is a load error
//! naming the state and field; evaluation errors (a path that selects nothing) are runtime
//! errors, which the interpreter reports as `States.Runtime`, as Step Functions does.

use serde_json::{Map, Value};

use super::intrinsic::Intrinsic;

/// One step of a path: an object field or an array index.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Step {
    /// `.name` or `['name']`.
    Field(String),
    /// `[n]`.
    Index(usize),
    /// `[*]`: every element of an array (template paths only).
    Each,
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
        Path::parse_with(text, false)
    }

    /// Parses the path of a template's `.$` field: a reference path that may also use `[*]`.
    pub fn parse_template(text: &str) -> Result<Path, String> {
        Path::parse_with(text, true)
    }

    /// True if the path has a `[*]` step (it then selects an array of matches).
    pub fn is_indefinite(&self) -> bool {
        self.steps.contains(&Step::Each)
    }

    fn parse_with(text: &str, wildcard: bool) -> Result<Path, String> {
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
                    if let Some(name) = inner.strip_prefix('\'').and_then(|s| s.strip_suffix('\''))
                    {
                        steps.push(Step::Field(name.to_owned()));
                    } else if inner == "*" && wildcard {
                        steps.push(Step::Each);
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

    /// The selected value, or `None` if a step finds no such field or index (or the path is
    /// indefinite: see [`Path::resolve`]).
    pub fn select<'v>(&self, input: &'v Value, context: &'v Value) -> Option<&'v Value> {
        let mut at = if self.context { context } else { input };
        for step in &self.steps {
            at = match step {
                Step::Field(name) => at.as_object()?.get(name)?,
                Step::Index(i) => at.as_array()?.get(*i)?,
                Step::Each => return None,
            };
        }
        Some(at)
    }

    /// Like [`Path::select`], but a miss is an error naming the path. An indefinite path
    /// (with `[*]`) never misses: it gives the array of its matches, possibly empty.
    pub fn resolve(&self, input: &Value, context: &Value) -> Result<Value, String> {
        if self.is_indefinite() {
            let root = if self.context { context } else { input };
            let mut out = Vec::new();
            collect(root, &self.steps, &mut out);
            return Ok(Value::Array(out));
        }
        self.select(input, context)
            .cloned()
            .ok_or_else(|| format!("the path {:?} selects nothing", self.text))
    }
}

/// Every value `steps` reach from `at`, in document order; dead ends are left out.
fn collect(at: &Value, steps: &[Step], out: &mut Vec<Value>) {
    let Some((step, rest)) = steps.split_first() else {
        out.push(at.clone());
        return;
    };
    match step {
        Step::Field(name) => {
            if let Some(v) = at.as_object().and_then(|o| o.get(name)) {
                collect(v, rest, out);
            }
        }
        Step::Index(i) => {
            if let Some(v) = at.as_array().and_then(|a| a.get(*i)) {
                collect(v, rest, out);
            }
        }
        Step::Each => {
            for v in at.as_array().into_iter().flatten() {
                collect(v, rest, out);
            }
        }
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
            return Err(format!(
                "ResultPath {text:?} cannot point into the context '$$'"
            ));
        }
        let mut fields = Vec::with_capacity(path.steps.len());
        for step in path.steps {
            match step {
                Step::Field(name) => fields.push(name),
                Step::Index(_) | Step::Each => {
                    return Err(format!(
                        "ResultPath {text:?}: array indices are not allowed"
                    ));
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
            Path::parse_template(text)
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
    fn template_paths_may_collect_with_a_wildcard() {
        let results = json!([{}, {"lost": {"task": 3}}, {"other": 1}, {"lost": {"task": 7}}]);
        let t = Template::compile(&json!({"lost.$": "$[*].lost", "tasks.$": "$[*].lost.task"}))
            .unwrap();
        assert_eq!(
            t.eval(&results, &json!({})).unwrap(),
            json!({"lost": [{"task": 3}, {"task": 7}], "tasks": [3, 7]})
        );
        assert_eq!(
            t.eval(&json!([{}, {}]), &json!({})).unwrap(),
            json!({"lost": [], "tasks": []})
        );
        assert_eq!(
            t.eval(&json!({}), &json!({})).unwrap(),
            json!({"lost": [], "tasks": []})
        );
        // Reference paths keep refusing it.
        assert!(Path::parse("$[*].lost").unwrap_err().contains("[*]"));
        assert!(ResultPath::parse(Some("$[*]")).is_err());
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
}
