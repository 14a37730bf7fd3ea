//! Serving a finished render's image within Lambda's response quota.
//!
//! The API runs behind API Gateway as a Lambda function, whose synchronous response is capped
//! at 6 MB, and `lambda_http` sends a binary body base64-encoded (4 bytes per 3). A PNG of a 4K
//! render, or the PFM of the default 960x540 one, is over it, and API Gateway would answer 500
//! after all the work. So an image over [`MAX_INLINE_BODY_BYTES`] is never returned in the
//! body: the answer is a `307` redirect to a presigned S3 GET of the stored object, which the
//! client (a browser, `curl -L`) fetches straight from S3. Smaller images are answered inline,
//! as before. An EXR is converted from the stored PFM; a large one is stored once
//! (`jobs/{job}/out/image.exr`) and redirected to like the others.

use hort_core::ids::JobId;
use hort_core::image::{decode_pfm, encode_exr};
use hort_core::keys::{FrameKeys, image_key};

use super::error::ApiError;

/// Image formats the API serves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// 8-bit sRGB PNG (the default).
    Png,
    /// Linear RGB Portable FloatMap, bit-exact.
    Pfm,
    /// Linear RGB OpenEXR, bit-exact.
    Exr,
}

impl ImageFormat {
    /// The format named by `?format=`.
    pub fn parse(name: &str) -> Option<ImageFormat> {
        match name {
            "png" => Some(ImageFormat::Png),
            "pfm" => Some(ImageFormat::Pfm),
            "exr" => Some(ImageFormat::Exr),
            _ => None,
        }
    }

    /// The file extension (`png`).
    pub fn extension(self) -> &'static str {
        match self {
            ImageFormat::Png => "png",
            ImageFormat::Pfm => "pfm",
            ImageFormat::Exr => "exr",
        }
    }

    /// The `Content-Type` of the format.
    pub fn content_type(self) -> &'static str {
        match self {
            ImageFormat::Png => "image/png",
            ImageFormat::Pfm => "image/x-portable-floatmap",
            ImageFormat::Exr => "image/x-exr",
        }
    }
}

/// The largest body the API answers inline: 4 MiB, whose base64 (5.6 MB) leaves room within
/// Lambda's 6 MB response ([`hort_aws_quotas::LAMBDA_SYNC_PAYLOAD_BYTES`]) for the headers and
/// the JSON envelope `lambda_http` wraps it in.
pub const MAX_INLINE_BODY_BYTES: usize = 4 << 20;

/// How long a presigned image URL stays valid.
pub const PRESIGNED_URL_SECONDS: u64 = 15 * 60;

/// What `GET /renders/{id}/image` answers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ImageAnswer {
    /// The image itself (at most [`MAX_INLINE_BODY_BYTES`]).
    Bytes(Vec<u8>),
    /// A presigned GET of the stored image, and its size in bytes.
    Redirect {
        /// The presigned URL.
        url: String,
        /// The object's size.
        bytes: u64,
    },
}

/// What [`stored_image`] needs of the bucket a backend keeps finished images in. `S3Store`
/// implements it (`src/s3_image_bucket.rs`, feature `aws`).
pub trait ImageBucket {
    /// The object's size, `None` if there is none.
    fn object_size(&self, key: &str) -> Result<Option<u64>, ApiError>;
    /// The object's bytes, `None` if there is none.
    fn object(&self, key: &str) -> Result<Option<Vec<u8>>, ApiError>;
    /// Stores an object (a converted image, kept for later requests).
    fn store(&self, key: &str, bytes: &[u8]) -> Result<(), ApiError>;
    /// A presigned GET of the object, valid for [`PRESIGNED_URL_SECONDS`].
    fn presigned_get(&self, key: &str) -> Result<String, ApiError>;
}

/// The image of the finished render `id` (job `job`; frame `frame`'s in a job of several
/// frames, 404 for a frame the job did not render) in `format`, from the outputs its Combine
/// task stored in `bucket`: the PNG or the PFM as stored, an EXR converted from the PFM; inline
/// up to [`MAX_INLINE_BODY_BYTES`], else a redirect to a presigned GET. A job whose request
/// asked for no linear image (`outputs.linear` false) has no PFM: then `pfm` and `exr` are 404
/// `not_found`, saying so.
pub fn stored_image(
    id: &str,
    job: &JobId,
    frame: Option<u32>,
    format: ImageFormat,
    bucket: &dyn ImageBucket,
) -> Result<ImageAnswer, ApiError> {
    let job = &FrameKeys { job, frame };
    if let Some(k) = frame
        && bucket.object_size(&image_key(job, "png"))?.is_none()
    {
        return Err(ApiError::not_found(format!("render {id} has no frame {k}")));
    }
    let missing = |extension: &str| match extension {
        "pfm" => ApiError::not_found(format!(
            "render {id} stored no linear image (its request's outputs.linear was false): \
             only format=png is served"
        )),
        _ => ApiError::internal(format!(
            "render {id} succeeded but its {extension} is missing"
        )),
    };
    let answer = |key: &str, bytes: u64| -> Result<ImageAnswer, ApiError> {
        if bytes > MAX_INLINE_BODY_BYTES as u64 {
            let url = bucket.presigned_get(key)?;
            return Ok(ImageAnswer::Redirect { url, bytes });
        }
        let body = bucket.object(key)?.ok_or_else(|| {
            ApiError::internal(format!("render {id}: {key} went missing while read"))
        })?;
        Ok(ImageAnswer::Bytes(body))
    };
    match format {
        ImageFormat::Png | ImageFormat::Pfm => {
            let key = image_key(job, format.extension());
            let size = bucket
                .object_size(&key)?
                .ok_or_else(|| missing(format.extension()))?;
            answer(&key, size)
        }
        ImageFormat::Exr => {
            let exr_key = image_key(job, "exr");
            if let Some(size) = bucket.object_size(&exr_key)? {
                return answer(&exr_key, size);
            }
            let pfm = bucket
                .object(&image_key(job, "pfm"))?
                .ok_or_else(|| missing("pfm"))?;
            let image = decode_pfm(&pfm)
                .map_err(|e| ApiError::internal(format!("the stored image of {id}: {e}")))?;
            let exr = encode_exr(&image)
                .map_err(|e| ApiError::internal(format!("cannot encode OpenEXR: {e}")))?;
            if exr.len() <= MAX_INLINE_BODY_BYTES {
                return Ok(ImageAnswer::Bytes(exr));
            }
            bucket.store(&exr_key, &exr)?;
            answer(&exr_key, exr.len() as u64)
        }
    }
}

/// Refuses a response Lambda would refuse: a body over 6 MB once `lambda_http` has encoded
/// it (base64 unless `text`). API Gateway answers such a response with a 500; so does this,
/// naming the size, so the local server fails where the deployment would.
pub fn check_response_size(bytes: usize, text: bool) -> Result<(), ApiError> {
    let limit = hort_aws_quotas::LAMBDA_SYNC_PAYLOAD_BYTES;
    let sent = if text {
        bytes
    } else {
        hort_aws_quotas::base64_len(bytes)
    };
    if sent <= limit {
        return Ok(());
    }
    Err(ApiError::internal(format!(
        "the response body of {bytes} bytes ({sent} as Lambda sends it) is over Lambda's \
         {limit}-byte response quota: API Gateway would answer 500"
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_inline_body_fits_a_lambda_response_once_base64_encoded_with_room_to_spare() {
        let sent = hort_aws_quotas::base64_len(MAX_INLINE_BODY_BYTES);
        assert!(sent + (256 << 10) <= hort_aws_quotas::LAMBDA_SYNC_PAYLOAD_BYTES);
        assert!(check_response_size(MAX_INLINE_BODY_BYTES, false).is_ok());
        // 4.5 MiB of binary is 6 MiB of base64: one byte more is over.
        assert!(check_response_size(4_718_592, false).is_ok());
        let e = check_response_size(4_718_593, false).unwrap_err();
        assert_eq!(
            e.message,
            "the response body of 4718593 bytes (6291460 as Lambda sends it) is over Lambda's \
             6291456-byte response quota: API Gateway would answer 500"
        );
        assert!(check_response_size(6_291_456, true).is_ok());
        assert!(check_response_size(6_291_457, true).is_err());
    }
}
