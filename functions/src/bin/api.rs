//! The HTTP API's Lambda entry point (`bootstrap` of the `ApiFunction` in
//! `infra/template.yaml`, behind an API Gateway HTTP API with IAM authorization): each request
//! goes to the router `hort_functions::api::handle` on a blocking thread, over the deployment's
//! backend (`hort_functions::aws::api_backend::AwsBackend`: S3, the intake queue, Step
//! Functions), built once per container. Settings: `hort_functions::aws::lambda::ApiSettings`.
#![forbid(unsafe_code)]

use std::sync::Arc;

use hort_functions::api::{ApiError, handle};
use hort_functions::aws::lambda::ApiSettings;
use lambda_http::{Body, Request, Response, service_fn};

fn main() -> Result<(), lambda_http::Error> {
    let settings = ApiSettings::from_env().map_err(|e| format!("api: {e}"))?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    runtime.block_on(async move {
        let backend = Arc::new(settings.backend().await.map_err(|e| format!("api: {e}"))?);
        lambda_http::run(service_fn(move |request: Request| {
            let backend = Arc::clone(&backend);
            async move {
                let (parts, body) = request.into_parts();
                let request = lambda_http::http::Request::from_parts(parts, body.to_vec());
                let response = tokio::task::spawn_blocking(move || handle(&*backend, request))
                    .await
                    .unwrap_or_else(|e| {
                        ApiError::internal(format!("the API handler panicked: {e}")).into_response()
                    });
                let (parts, body) = response.into_parts();
                Ok::<_, lambda_http::Error>(Response::from_parts(parts, Body::from(body)))
            }
        }))
        .await
    })
}
