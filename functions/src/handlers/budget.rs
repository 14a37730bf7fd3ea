//! The budget of a job accepted on an estimate (`JobRequest::budget`: a scene given by key,
//! which the HTTP API does not load), checked again by the Plan function on the scene as
//! loaded, before any Map runs: the request's `max_cost_usd` holds for the job that runs, not
//! only for the estimate it was accepted on.

use super::HandlerError;
use super::events::JobRequest;
use hort_core::pipeline::JobPlan;
use hort_core::plural::count;
use hort_core::predict::{predict, usd};

/// `Hort.BadInput` when the cost predicted for `plan` (with the model the API predicted with)
/// is over the request's budget; nothing for a job without one.
pub(super) fn check_budget(request: &JobRequest, plan: &JobPlan) -> Result<(), HandlerError> {
    let Some(budget) = &request.budget else {
        return Ok(());
    };
    let prediction = predict(plan, &budget.model);
    if prediction.predicted_cost_usd <= budget.max_cost_usd {
        return Ok(());
    }
    Err(HandlerError::bad_input(format!(
        "the predicted cost {} of the scene as loaded ({}, {}, about {:.1} s) is \
         over the budget max_cost_usd = {}: the job was accepted on an estimate from the \
         scene's file sizes; raise the budget or render fewer pixels or samples",
        usd(prediction.predicted_cost_usd),
        count(plan.triangles, "triangle"),
        count(prediction.tasks_total, "task"),
        prediction.predicted_seconds,
        usd(budget.max_cost_usd),
    )))
}
