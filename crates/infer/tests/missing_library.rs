//! A missing ONNX Runtime library is an error naming the path, not a panic. (Its own test binary:
//! the environment is created once per process.)
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

#[test]
fn missing_library_is_a_clear_error() {
    let e = unitac_infer::runtime::environment(Some(std::path::Path::new(
        "/nonexistent/libonnxruntime.so.1.31.1",
    )))
    .map(|_| ())
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("/nonexistent/libonnxruntime.so.1.31.1") && e.contains("does not exist"),
        "{e}"
    );
    // Asking again gives the same error (one environment per process, never retried with panics).
    assert!(unitac_infer::runtime::environment(None).is_err());
}
