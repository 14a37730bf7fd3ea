//! The deployment in miniature: each function's memory, timeout, reserved concurrency and
//! `/tmp`, read from `infra/template.yaml` (compiled into this crate) with every parameter at its
//! default, so a change to the template changes what the emulator allows.
//!
//! The template is CloudFormation YAML; this module evaluates the few intrinsic functions its
//! function properties use (`!Ref` of a parameter or `AWS::NoValue`, `!If` on a condition,
//! `!Not`, `!Equals`) over the parameters' defaults, and refuses anything else with the
//! property named, so a template the emulator cannot follow fails its tests, not a user's run.

use std::sync::OnceLock;

use asl_interpreter::{FunctionLimit, FunctionLimits};
use hort_aws_quotas::LAMBDA_DEFAULT_TMP_MB;
use hort_core::stage::{PLAN_FUNCTION, WORKER_FUNCTION};
use serde_norway::Value;

/// The deployment template's text, exactly as deployed.
pub const TEMPLATE: &str = include_str!("../../infra/template.yaml");

/// One function's settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FunctionSettings {
    /// `MemorySize`, MB.
    pub memory_mb: u32,
    /// `Timeout`, seconds.
    pub timeout_seconds: u32,
    /// `ReservedConcurrentExecutions`; `None`: unreserved.
    pub reserved_concurrency: Option<u32>,
    /// `EphemeralStorage.Size` (`/tmp`), MB; Lambda's 512 when not set.
    pub tmp_mb: u32,
}

/// The settings of the functions the emulator runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Deployment {
    /// `PlanFunction`: splits scenes, plans jobs, finds a Map's lost items.
    pub plan: FunctionSettings,
    /// `WorkerFunction`: every task.
    pub worker: FunctionSettings,
    /// `ApiFunction`: the HTTP API (`hort serve`).
    pub api: FunctionSettings,
}

impl Deployment {
    /// The settings of `infra/template.yaml` at its parameters' defaults.
    pub fn bundled() -> &'static Deployment {
        static BUNDLED: OnceLock<Deployment> = OnceLock::new();
        BUNDLED.get_or_init(|| {
            Deployment::from_template(TEMPLATE)
                .unwrap_or_else(|e| panic!("infra/template.yaml, compiled into hort: {e}"))
        })
    }

    /// Reads a template's function settings at its parameters' defaults.
    pub fn from_template(text: &str) -> Result<Deployment, String> {
        let template: Value = serde_norway::from_str(text).map_err(|e| format!("not YAML: {e}"))?;
        let eval = Evaluator {
            template: &template,
        };
        Ok(Deployment {
            plan: eval.function("PlanFunction")?,
            worker: eval.function("WorkerFunction")?,
            api: eval.function("ApiFunction")?,
        })
    }

    /// What the state machine's interpreter holds the Plan and Worker functions to: their
    /// reserved concurrency and timeouts.
    pub fn function_limits(&self) -> FunctionLimits {
        let limit = |f: &FunctionSettings| FunctionLimit {
            reserved_concurrency: f.reserved_concurrency.map(|n| n as usize),
            timeout_seconds: Some(f64::from(f.timeout_seconds)),
        };
        FunctionLimits::none()
            .with(PLAN_FUNCTION, limit(&self.plan))
            .with(WORKER_FUNCTION, limit(&self.worker))
    }
}

struct Evaluator<'a> {
    template: &'a Value,
}

impl Evaluator<'_> {
    fn function(&self, name: &str) -> Result<FunctionSettings, String> {
        let resource = &self.template["Resources"][name];
        if resource.is_null() {
            return Err(format!("no resource {name}"));
        }
        let properties = &resource["Properties"];
        let globals = &self.template["Globals"]["Function"];
        let property = |key: &str| -> Result<Option<u64>, String> {
            let value = match &properties[key] {
                Value::Null => &globals[key],
                value => value,
            };
            self.number(value)
                .map_err(|e| format!("{name}.Properties.{key}: {e}"))
        };
        let required = |key: &str| -> Result<u32, String> {
            let n = property(key)?.ok_or_else(|| format!("{name}.Properties.{key} is not set"))?;
            u32::try_from(n).map_err(|_| format!("{name}.Properties.{key}: {n} is too large"))
        };
        let tmp_mb = match &properties["EphemeralStorage"]["Size"] {
            Value::Null => LAMBDA_DEFAULT_TMP_MB,
            size => self
                .number(size)
                .map_err(|e| format!("{name}.Properties.EphemeralStorage.Size: {e}"))?
                .unwrap_or(LAMBDA_DEFAULT_TMP_MB),
        };
        Ok(FunctionSettings {
            memory_mb: required("MemorySize")?,
            timeout_seconds: required("Timeout")?,
            reserved_concurrency: property("ReservedConcurrentExecutions")?
                .map(|n| u32::try_from(n).unwrap_or(u32::MAX)),
            tmp_mb: u32::try_from(tmp_mb).unwrap_or(u32::MAX),
        })
    }

    /// A number, or `None` for `!Ref AWS::NoValue` (the property is left out).
    fn number(&self, value: &Value) -> Result<Option<u64>, String> {
        match self.eval(value)? {
            Evaluated::NoValue => Ok(None),
            Evaluated::Value(Value::Number(n)) => n
                .as_u64()
                .map(Some)
                .ok_or_else(|| format!("{n} is not a whole number")),
            Evaluated::Value(Value::String(s)) => s
                .parse()
                .map(Some)
                .map_err(|_| format!("{s:?} is not a number")),
            Evaluated::Value(other) => Err(format!("{other:?} is not a number")),
        }
    }

    fn eval(&self, value: &Value) -> Result<Evaluated, String> {
        let Value::Tagged(tagged) = value else {
            return Ok(Evaluated::Value(value.clone()));
        };
        let args = &tagged.value;
        match tagged.tag.to_string().as_str() {
            "!Ref" => match args.as_str() {
                Some("AWS::NoValue") => Ok(Evaluated::NoValue),
                Some(parameter) => {
                    let default = &self.template["Parameters"][parameter]["Default"];
                    if default.is_null() {
                        Err(format!("!Ref {parameter}: no parameter with a Default"))
                    } else {
                        Ok(Evaluated::Value(default.clone()))
                    }
                }
                None => Err(format!("!Ref of {args:?}")),
            },
            "!If" => {
                let [condition, then, otherwise] = self.list::<3>(args, "!If")?;
                let name = condition
                    .as_str()
                    .ok_or_else(|| format!("!If on {condition:?}"))?;
                let holds = self.condition(&self.template["Conditions"][name])?;
                self.eval(if holds { then } else { otherwise })
            }
            tag => Err(format!("{tag} is not understood here")),
        }
    }

    fn condition(&self, value: &Value) -> Result<bool, String> {
        let Value::Tagged(tagged) = value else {
            return Err(format!("condition {value:?}"));
        };
        match tagged.tag.to_string().as_str() {
            "!Not" => {
                let [inner] = self.list::<1>(&tagged.value, "!Not")?;
                Ok(!self.condition(inner)?)
            }
            "!Equals" => {
                let [a, b] = self.list::<2>(&tagged.value, "!Equals")?;
                Ok(scalar(self.eval(a)?) == scalar(self.eval(b)?))
            }
            tag => Err(format!("condition {tag} is not understood here")),
        }
    }

    fn list<'v, const N: usize>(
        &self,
        value: &'v Value,
        what: &str,
    ) -> Result<[&'v Value; N], String> {
        let items: Vec<&Value> = value
            .as_sequence()
            .map(|s| s.iter().collect())
            .unwrap_or_default();
        items
            .try_into()
            .map_err(|_| format!("{what} takes {N} arguments, found {value:?}"))
    }
}

enum Evaluated {
    Value(Value),
    NoValue,
}

/// A scalar as CloudFormation compares it: as text.
fn scalar(value: Evaluated) -> Option<String> {
    match value {
        Evaluated::Value(Value::Number(n)) => Some(n.to_string()),
        Evaluated::Value(Value::String(s)) => Some(s),
        Evaluated::Value(Value::Bool(b)) => Some(b.to_string()),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bundled_template_sets_each_function() {
        let d = Deployment::bundled();
        assert_eq!(
            d.worker,
            FunctionSettings {
                memory_mb: 2048,
                timeout_seconds: 120,
                reserved_concurrency: Some(100),
                tmp_mb: 512,
            }
        );
        assert_eq!(
            d.plan,
            FunctionSettings {
                memory_mb: 3008,
                timeout_seconds: 900,
                reserved_concurrency: Some(5),
                tmp_mb: 10240,
            }
        );
        assert_eq!(d.api.timeout_seconds, 29);
        assert_eq!(d.api.reserved_concurrency, Some(10));
        // The plan's default memory is the deployed Worker's.
        assert_eq!(d.worker.memory_mb, hort_core::pipeline::DEFAULT_MEMORY_MB);
    }

    #[test]
    fn a_template_change_changes_the_settings_and_what_cannot_be_followed_is_named() {
        let unreserved = TEMPLATE.replace(
            "  WorkerConcurrency:\n    Type: Number\n    Default: 100",
            "  WorkerConcurrency:\n    Type: Number\n    Default: 0",
        );
        assert_ne!(unreserved, TEMPLATE);
        let d = Deployment::from_template(&unreserved).unwrap();
        assert_eq!(d.worker.reserved_concurrency, None);
        assert_eq!(d.plan.reserved_concurrency, None);
        let bigger = TEMPLATE.replace(
            "  WorkerMemoryMB:\n    Type: Number\n    Default: 2048",
            "  WorkerMemoryMB:\n    Type: Number\n    Default: 4096",
        );
        assert_eq!(
            Deployment::from_template(&bigger).unwrap().worker.memory_mb,
            4096
        );
        let odd = TEMPLATE.replace(
            "Timeout: !Ref WorkerTimeoutSeconds",
            "Timeout: !GetAtt Something.Timeout",
        );
        assert_eq!(
            Deployment::from_template(&odd).unwrap_err(),
            "WorkerFunction.Properties.Timeout: !GetAtt is not understood here"
        );
    }
}
