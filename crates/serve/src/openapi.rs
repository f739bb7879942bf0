//! The OpenAPI 3.1 document of API v1, served at `GET /v1/openapi.json`. Written by hand next
//! to the routes; a test checks it lists exactly [`crate::router::ROUTES`].

use serde_json::{Value, json};

fn error_response(description: &str) -> Value {
    json!({
        "description": description,
        "content": { "application/json": { "schema": { "$ref": "#/components/schemas/Error" } } }
    })
}

fn secured(mut op: Value) -> Value {
    op["security"] = json!([{ "bearer": [] }]);
    let responses = &mut op["responses"];
    responses["401"] = error_response("no or unknown bearer token (`unauthorized`)");
    op
}

fn session_op(summary: &str, ok: Value) -> Value {
    let mut op = secured(json!({
        "summary": summary,
        "parameters": [{ "name": "id", "in": "path", "required": true, "schema": { "type": "string" } }],
        "responses": { "200": ok }
    }));
    op["responses"]["404"] = error_response("no such session for this token (`session_not_found`)");
    op
}

/// The document.
pub fn document() -> Value {
    let estimate_ref = json!({ "$ref": "#/components/schemas/Estimate" });
    let session_ref = json!({ "$ref": "#/components/schemas/Session" });
    let json_ok = |description: &str, schema: Value| json!({ "description": description, "content": { "application/json": { "schema": schema } } });
    let mut post_samples = session_op(
        "Post a batch of samples (stream order); answers the estimates it made",
        json_ok(
            "accepted",
            json!({ "type": "object", "properties": {
                "accepted": { "type": "integer" },
                "estimates": { "type": "array", "items": estimate_ref },
                "estimate": estimate_ref
            }}),
        ),
    );
    post_samples["requestBody"] = json!({
        "required": true,
        "content": { "application/json": { "schema": { "$ref": "#/components/schemas/Batch" } } }
    });
    post_samples["responses"]["400"] = error_response(
        "malformed JSON (`malformed_body`), an invalid sample (`invalid_sample`, with `index` and `field`), a sample before the session's latest in stream order (`out_of_order`)",
    );
    post_samples["responses"]["409"] = error_response("the session is closed (`session_closed`)");
    post_samples["responses"]["413"] = error_response("body over the limit (`body_too_large`)");
    post_samples["responses"]["429"] =
        error_response("over the session's sample rate (`rate_limited`, with Retry-After)");
    let mut track = session_op(
        "The session's track",
        json!({ "description": "the track", "content": {
            "application/geo+json": { "schema": { "type": "object" } },
            "text/csv": { "schema": { "type": "string" } },
            "application/json": { "schema": { "type": "object" } }
        }}),
    );
    if let Some(p) = track["parameters"].as_array_mut() {
        p.push(json!({ "name": "format", "in": "query", "required": false,
            "schema": { "type": "string", "enum": ["geojson", "ipin", "csv", "json"], "default": "geojson" },
            "description": "geojson: a Feature (lon/lat where the model has a WGS84 frame, else metres); ipin: t_s,lat,lon,floor at 2 Hz (needs a WGS84 frame, else 409 `format_unavailable`); csv: t_ms,x,y,floor,sd_m; json: the estimates" }))
    }
    let sse = |summary: &str| json!({ "description": summary, "content": { "text/event-stream": { "schema": { "type": "string" } } } });
    let mut create = secured(json!({
        "summary": "Open a session",
        "requestBody": { "required": true, "content": { "application/json": { "schema": { "$ref": "#/components/schemas/CreateSession" } } } },
        "responses": { "201": json_ok("opened", session_ref.clone()) }
    }));
    create["responses"]["400"] =
        error_response("bad field (`invalid_field`) or JSON (`malformed_body`)");
    create["responses"]["429"] = error_response(
        "the token has its most open sessions (`too_many_sessions`), or the server opens sessions faster than `--max-opens-per-s` (`too_many_opens`, with Retry-After)",
    );
    json!({
        "openapi": "3.1.0",
        "info": {
            "title": "wipdr serve",
            "version": "1",
            "description": "Indoor positioning as a service: open a session, post sample batches (the plain sample stream of wipdr_io::sample_stream as JSON), read estimates and tracks. Errors are {\"error\": {\"code\", \"message\", \"index\"?, \"field\"?}}."
        },
        "components": {
            "securitySchemes": { "bearer": { "type": "http", "scheme": "bearer" } },
            "schemas": {
                "Error": { "type": "object", "required": ["error"], "properties": { "error": {
                    "type": "object", "required": ["code", "message"], "properties": {
                        "code": { "type": "string" }, "message": { "type": "string" },
                        "index": { "type": "integer" }, "field": { "type": "string" } } } } },
                "Estimate": { "type": "object", "properties": {
                    "t_ms": { "type": "integer" }, "x": { "type": "number" }, "y": { "type": "number" },
                    "floor": { "type": ["integer", "null"] }, "sd_m": { "type": ["number", "null"] },
                    "r95_m": { "type": ["number", "null"] } } },
                "Session": { "type": "object", "properties": {
                    "id": { "type": "string" }, "scheme": { "type": "string" }, "device": { "type": "string" },
                    "stream_id": { "type": "string" }, "state": { "type": "string", "enum": ["open", "closed"] },
                    "close_reason": { "type": ["string", "null"] }, "samples": { "type": ["integer", "null"] },
                    "estimates": { "type": ["integer", "null"] }, "estimate": estimate_ref } },
                "CreateSession": { "type": "object", "required": ["device"], "additionalProperties": false, "properties": {
                    "scheme": { "type": "string", "default": "pmf" }, "device": { "type": "string", "maxLength": 200 },
                    "stream_id": { "type": "string", "description": "the positioner's seed (default: the session id); the walk id reproduces wipdr locate" },
                    "phone_model": { "type": "string" }, "start_unix_ms": { "type": "integer" } } },
                "Sample": { "type": "object", "required": ["sensor"], "description": "one plain sample: {t_ms, sensor: accelerometer|gyroscope|magnetometer|rotation_vector, x, y, z}, {t_ms, sensor: pressure, hpa}, {t_ms, sensor: wifi, aps: [{bssid, rssi_dbm, last_seen_ms?}]}",
                    "properties": { "t_ms": { "type": "integer" }, "sensor": { "type": "string",
                        "enum": ["accelerometer", "gyroscope", "magnetometer", "rotation_vector", "pressure", "wifi"] } } },
                "Batch": { "type": "object", "required": ["samples"], "additionalProperties": false, "properties": {
                    "samples": { "type": "array", "items": { "$ref": "#/components/schemas/Sample" } } } }
            }
        },
        "paths": {
            "/": { "get": { "summary": "The live map page (token in the URL fragment: /#token=...)", "responses": { "200": { "description": "HTML" } } } },
            "/map.js": { "get": { "summary": "The live map's script", "responses": { "200": { "description": "JavaScript" } } } },
            "/healthz": { "get": { "summary": "Liveness", "responses": { "200": { "description": "ok" } } } },
            "/metrics": { "get": { "summary": "Prometheus metrics (text format)", "responses": { "200": { "description": "metrics" } } } },
            "/v1/openapi.json": { "get": { "summary": "This document", "responses": { "200": { "description": "OpenAPI 3.1" } } } },
            "/v1/plan": { "get": secured(json!({ "summary": "The site's floor plan (metres) for the map", "responses": { "200": json_ok("plan", json!({ "type": "object" })) } })) },
            "/v1/sessions": {
                "get": secured(json!({ "summary": "The token's open sessions with their recent estimates", "responses": { "200": json_ok("sessions", json!({ "type": "object" })) } })),
                "post": create
            },
            "/v1/sessions/{id}": {
                "get": session_op("A session's state and current estimate", json_ok("the session", session_ref.clone())),
                "delete": session_op("Close a session (its track stays readable)", json_ok("closed", session_ref))
            },
            "/v1/sessions/{id}/samples": { "post": post_samples },
            "/v1/sessions/{id}/track": { "get": track },
            "/v1/sessions/{id}/events": { "get": session_op("The session's estimates, live (Server-Sent Events `estimate`, `closed`, `lagged`), starting with its latest estimate", sse("event stream")) },
            "/v1/live": { "get": secured(json!({ "summary": "Every open session of the token, live (Server-Sent Events), starting with each one's latest estimate", "responses": { "200": sse("event stream") } })) }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    #[test]
    fn the_document_lists_exactly_the_routes() {
        let doc = document();
        let mut listed = BTreeSet::new();
        for (path, ops) in doc["paths"].as_object().unwrap() {
            for method in ops.as_object().unwrap().keys() {
                listed.insert((method.clone(), path.clone()));
            }
        }
        let routes: BTreeSet<(String, String)> = crate::router::ROUTES
            .iter()
            .map(|(m, p)| (m.to_string(), p.to_string()))
            .collect();
        assert_eq!(listed, routes);
    }
}
