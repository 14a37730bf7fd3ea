//! [`S3Store`] as the API router's [`ImageBucket`]: a finished render's image read, stored and
//! presigned in the bucket, so `stored_image` redirects a client to S3 for an image over a
//! Lambda response. Here, not in `api`, so the router builds without the AWS SDK.

use std::time::Duration;

use hort_core::store::{BlobStore, StoreError};

use crate::S3Store;
use crate::api::{ApiError, ImageBucket, PRESIGNED_URL_SECONDS};

impl ImageBucket for S3Store {
    fn object_size(&self, key: &str) -> Result<Option<u64>, ApiError> {
        match self.size(key) {
            Ok(n) => Ok(Some(n)),
            Err(StoreError::NotFound { .. }) => Ok(None),
            Err(e) => Err(ApiError::internal(format!("cannot read {key}: {e}"))),
        }
    }

    fn object(&self, key: &str) -> Result<Option<Vec<u8>>, ApiError> {
        match self.get(key) {
            Ok(bytes) => Ok(Some(bytes)),
            Err(StoreError::NotFound { .. }) => Ok(None),
            Err(e) => Err(ApiError::internal(format!("cannot read {key}: {e}"))),
        }
    }

    fn store(&self, key: &str, bytes: &[u8]) -> Result<(), ApiError> {
        self.put(key, bytes)
            .map_err(|e| ApiError::internal(format!("cannot store {key}: {e}")))
    }

    fn presigned_get(&self, key: &str) -> Result<String, ApiError> {
        S3Store::presigned_get(self, key, Duration::from_secs(PRESIGNED_URL_SECONDS))
            .map_err(|e| ApiError::internal(format!("cannot presign {key}: {e}")))
    }
}
