//! The live map page at `/`: the site's floor plan with every open session of a token, its
//! estimate, 95 % circle and recent track, updated live from `GET /v1/live` (Server-Sent
//! Events read with `fetch`, so the token goes in a header, never in a URL the server sees:
//! the page reads it from the URL fragment, `/#token=...`, or asks for it).
//!
//! Every string from the server (device labels, scheme names, ids) is inserted as text
//! (`textContent`, canvas `fillText`), never as HTML; the page's Content-Security-Policy allows
//! only its own script.

use axum::http::header;
use axum::response::IntoResponse;

/// The page.
pub const INDEX_HTML: &str = include_str!("page/index.html");
/// Its script.
pub const MAP_JS: &str = include_str!("page/map.js");

const CSP: &str = "default-src 'none'; script-src 'self'; connect-src 'self'; style-src 'unsafe-inline'; img-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'";

/// `GET /`.
pub async fn index() -> impl IntoResponse {
    (
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (header::CONTENT_SECURITY_POLICY, CSP),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
            (header::REFERRER_POLICY, "no-referrer"),
        ],
        INDEX_HTML,
    )
}

/// `GET /map.js`.
pub async fn script() -> impl IntoResponse {
    (
        [
            (header::CONTENT_TYPE, "text/javascript; charset=utf-8"),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
        ],
        MAP_JS,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_script_never_inserts_html() {
        for banned in [
            "innerHTML",
            "outerHTML",
            "insertAdjacentHTML",
            "document.write",
            "eval(",
        ] {
            assert!(!MAP_JS.contains(banned), "map.js uses {banned}");
            assert!(!INDEX_HTML.contains(banned), "index.html uses {banned}");
        }
        assert!(
            !INDEX_HTML.contains("<script>"),
            "no inline script (the CSP forbids it)"
        );
    }
}
