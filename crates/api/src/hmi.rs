//! The web HMI: the built bundle of `web/` (committed in `web/dist`, checked against the
//! sources by `scripts/hmi.sh check`) embedded in the binary and served at `/`.
//! docs/hmi.md describes it.

use axum::http::{HeaderValue, StatusCode, Uri, header};
use axum::response::{IntoResponse, Response};
use include_dir::{Dir, include_dir};

static BUNDLE: Dir<'static> = include_dir!("$CARGO_MANIFEST_DIR/../../web/dist");

fn content_type(path: &str) -> &'static str {
    match path.rsplit('.').next().unwrap_or("") {
        "html" => "text/html; charset=utf-8",
        "js" | "mjs" => "text/javascript; charset=utf-8",
        "css" => "text/css; charset=utf-8",
        "svg" => "image/svg+xml",
        "png" => "image/png",
        "json" | "map" => "application/json",
        "woff2" => "font/woff2",
        "ico" => "image/x-icon",
        "txt" => "text/plain; charset=utf-8",
        _ => "application/octet-stream",
    }
}

/// A file of the bundle, or `index.html` for any other path outside `/api` (the HMI
/// routes its screens in the browser).
pub async fn serve(uri: Uri) -> Response {
    let path = uri.path().trim_start_matches('/');
    let (file, immutable) = match BUNDLE.get_file(path) {
        // Vite names the assets by their content hash: they never change under their name.
        Some(f) if !path.is_empty() => (f, path.starts_with("assets/")),
        _ => match BUNDLE.get_file("index.html") {
            Some(f) => (f, false),
            None => {
                return (StatusCode::NOT_FOUND, "the HMI bundle is missing").into_response();
            }
        },
    };
    let name = file.path().to_string_lossy();
    let cache = if immutable {
        "public, max-age=31536000, immutable"
    } else {
        "no-cache"
    };
    let mut r = file.contents().into_response();
    let h = r.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static(content_type(&name)),
    );
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static(cache));
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    r
}

/// Whether the bundle has its page (false only for a broken checkout).
pub fn present() -> bool {
    BUNDLE.get_file("index.html").is_some()
}
