//! The dashboard's HTTP face against real processes on 127.0.0.1: a coordinator with `--http-listen` and
//! client/worker tokens, and a worker. Checks status codes, 401/403 refusals, the JSON shapes the page reads,
//! the fixed-name file route (and that traversal attempts reach nothing), the actions, the event stream, the
//! login cookie, and HTTPS with the coordinator's own certificate.

mod dashboard_support;

use crease_e2e::*;
use dashboard_support::*;

fn assert_json_error(r: &Resp, status: u16) {
    assert_eq!(r.status, status, "{}\n{}", r.head, r.text());
    assert!(
        r.header("content-type")
            .is_some_and(|t| t.starts_with("application/json")),
        "{}",
        r.head
    );
    assert!(r.json()["error"].as_str().is_some_and(|e| !e.is_empty()));
}

#[test]
fn the_api_serves_jobs_workers_files_actions_and_events_to_client_tokens_only() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let port = free_port();
    let c = start(d, port, &[]);
    let _w = c.worker("w-api", &[("CREASE_TEST_TASK_DELAY", "position=150")]);
    let dash = Dash {
        addr: format!("127.0.0.1:{port}"),
        ca: None,
    };
    let (job_toml, out) = job(d, "api");
    let id = c.submit(&job_toml);
    let client = Auth::Bearer(CLIENT_TOKEN);

    // Refusals: no token and unknown tokens are 401, the worker token is 403, on data and actions alike.
    for path in [
        "/api/jobs",
        &format!("/api/jobs/{id}"),
        "/api/workers",
        "/api/events",
    ] {
        assert_json_error(&dash.get(path, Auth::None), 401);
        assert_json_error(&dash.get(path, Auth::Bearer("guess")), 401);
        let r = dash.get(path, Auth::Bearer(WORKER_TOKEN));
        assert_json_error(&r, 403);
        assert!(!r.text().contains(WORKER_TOKEN), "{}", r.text());
    }
    assert_json_error(
        &dash.post(&format!("/api/jobs/{id}/cancel"), Auth::None),
        401,
    );
    assert_json_error(
        &dash.post(
            &format!("/api/jobs/{id}/cancel"),
            Auth::Bearer(WORKER_TOKEN),
        ),
        403,
    );
    // The page itself sends a browser to the login form; the static assets hold no data and are public.
    let r = dash.get("/", Auth::None);
    assert_eq!(r.status, 303);
    assert_eq!(r.header("location").as_deref(), Some("/login"));
    assert_eq!(dash.get("/login", Auth::None).status, 200);
    let js = dash.get("/assets/app.js", Auth::None);
    assert_eq!(js.status, 200);
    assert!(js.text().contains("EventSource"));
    assert!(js
        .header("content-security-policy")
        .is_some_and(|p| p.contains("script-src 'self'")));

    // Live events: a snapshot of the jobs first, then the job's own events as it runs.
    let stream = dash.events_until(client, "event: job\n");
    assert!(stream.starts_with("HTTP/1.1 200"), "{stream}");
    assert!(stream.contains("text/event-stream"), "{stream}");
    assert!(stream.contains("event: jobs\n"), "{stream}");
    assert!(stream.contains(&format!("\"id\":\"{id}\"")), "{stream}");
    assert!(stream.contains("event: workers\n"), "{stream}");

    c.wait_state(&id, &["done"]);

    // The jobs list and its filter.
    let r = dash.get("/api/jobs", client);
    assert_eq!(r.status, 200, "{}", r.text());
    assert_eq!(r.header("cache-control").as_deref(), Some("no-store"));
    let jobs = r.json();
    let j = &jobs["jobs"][0];
    assert_eq!(j["id"], id.as_str());
    assert_eq!(j["name"], "api");
    assert_eq!(j["state"], "done");
    assert!(j["priority"].is_i64());
    let t = &j["tasks"];
    assert!(t["total"].as_u64().unwrap() > 5, "{t}");
    assert_eq!(t["done"], t["total"]);
    assert_eq!(t["running"], 0);
    assert_eq!(t["failed"], 0);
    assert_eq!(t["queued"], 0);
    assert!(j["submitted_unix"].as_f64().unwrap() > 1.6e9);
    assert!(j["finished_unix"].as_f64().unwrap() >= j["submitted_unix"].as_f64().unwrap());
    assert!(j["duration_secs"].as_f64().unwrap() > 0.0);
    let done = dash.get("/api/jobs?state=done", client).json();
    assert_eq!(done["jobs"].as_array().unwrap().len(), 1);
    let running = dash.get("/api/jobs?state=running,queued", client).json();
    assert_eq!(running["jobs"].as_array().unwrap().len(), 0);
    let bad = dash.get("/api/jobs?state=bogus", client);
    assert_json_error(&bad, 400);
    assert!(bad.text().contains("bogus"));

    // One job: stages in graph order with their tasks and log tails, pictures, report figures.
    let jr = dash.get(&format!("/api/jobs/{id}"), client).json();
    let kinds: Vec<&str> = jr["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["kind"].as_str().unwrap())
        .collect();
    assert_eq!(
        kinds,
        ["relief", "weight-block", "reduce", "position", "finalize"]
    );
    let stage_total: u64 = jr["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["counts"]["total"].as_u64().unwrap())
        .sum();
    assert_eq!(stage_total, t["total"].as_u64().unwrap());
    let fin = &jr["stages"][4]["tasks"][0];
    assert_eq!(fin["key"], "finalize");
    assert_eq!(fin["state"], "done");
    assert_eq!(fin["attempts"], 1);
    assert!(fin["worker"].as_str().unwrap().starts_with('w'), "{fin}");
    assert!(fin["work_secs"].as_f64().unwrap() > 0.0);
    let log = &fin["logs"][0];
    assert_eq!(log["attempt"], 1);
    assert!(
        log["lines"]
            .as_array()
            .unwrap()
            .iter()
            .any(|l| l.as_str().unwrap().contains("dispatched to worker")),
        "{log}"
    );
    let names: Vec<&str> = jr["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["preview.png", "stretch.png"]);
    assert_eq!(
        jr["files"][0]["url"],
        format!("/api/jobs/{id}/files/preview.png")
    );
    assert_eq!(jr["report"]["complete"], true);
    assert_eq!(jr["report"]["summary"]["frames"], 4);

    // Files: the job's own, byte for byte, by fixed name only.
    let png = dash.get(&format!("/api/jobs/{id}/files/preview.png"), client);
    assert_eq!(png.status, 200);
    assert_eq!(png.header("content-type").as_deref(), Some("image/png"));
    assert_eq!(png.body, std::fs::read(out.join("preview.png")).unwrap());
    assert_json_error(
        &dash.get(&format!("/api/jobs/{id}/files/eval.png"), client),
        404,
    );
    std::fs::write(d.join("secret.txt"), "root:x:0:0:not-for-the-web\n").unwrap();
    for path in [
        format!("/api/jobs/{id}/files/..%2f..%2fetc%2fpasswd"),
        format!("/api/jobs/{id}/files/..%2fsecret.txt"),
        format!("/api/jobs/{id}/files/%2e%2e%2f%2e%2e%2fsecret.txt"),
        format!("/api/jobs/{id}/files/../../secret.txt"),
        format!("/api/jobs/{id}/files/report.json"),
        format!("/api/jobs/{id}/files/.crease-work%2fpositions%2ff000000.npy"),
        format!("/api/jobs/{id}/files/overlay-..%2f1.png"),
        "/api/jobs/..%2f..%2fetc/files/preview.png".to_string(),
        "/api/jobs/..%2fapi-out/files/preview.png".to_string(),
        "/assets/..%2f..%2fCargo.toml".to_string(),
        "/assets/../../Cargo.toml".to_string(),
        "/etc/passwd".to_string(),
    ] {
        let r = dash.get(&path, client);
        assert_eq!(r.status, 404, "{path}: {}\n{}", r.head, r.text());
        let body = r.text();
        assert!(
            !body.contains("root:") && !body.contains("[workspace]"),
            "{path}: {body}"
        );
    }
    assert_json_error(&dash.get("/api/jobs/job-99999", client), 404);

    // Workers.
    let ws = dash.get("/api/workers", client).json();
    let w = &ws["workers"][0];
    assert_eq!(w["name"], "w-api");
    assert!(w["capacity"].as_u64().unwrap() >= 1);
    assert_eq!(w["running"], 0);
    assert_eq!(w["draining"], false);
    assert!(w["last_heartbeat_secs"].as_f64().unwrap() < 5.0, "{w}");
    assert!(w["tasks"].as_array().unwrap().is_empty());

    // Actions: resubmit makes a new job with the same spec; cancel stops it; a cross-site POST is refused.
    let r = dash.post(&format!("/api/jobs/{id}/resubmit"), client);
    assert_eq!(r.status, 201, "{}", r.text());
    let again = r.json()["id"].as_str().unwrap().to_string();
    assert_ne!(again, id);
    assert_eq!(r.json()["resubmitted_from"], id.as_str());
    let r = dash.req(
        "POST",
        &format!("/api/jobs/{again}/cancel"),
        &[
            ("Authorization", &format!("Bearer {CLIENT_TOKEN}")),
            ("Origin", "http://evil.example"),
        ],
        b"",
    );
    assert_json_error(&r, 403);
    let r = dash.post(&format!("/api/jobs/{again}/cancel"), client);
    assert_eq!(r.status, 200, "{}", r.text());
    assert_eq!(r.json()["state"], "cancelled");
    assert_eq!(c.status(&again)["state"], "cancelled");
    assert_json_error(&dash.post("/api/jobs/job-99999/cancel", client), 404);
    assert_eq!(
        dash.get(&format!("/api/jobs/{id}/cancel"), client).status,
        405
    );

    // The login form: a worker token is 403, a wrong one 401, the client token sets an HttpOnly cookie that
    // then works like the bearer header.
    let form = |token: &str| {
        dash.req(
            "POST",
            "/login",
            &[("Content-Type", "application/x-www-form-urlencoded")],
            format!("token={token}").as_bytes(),
        )
    };
    let r = form(WORKER_TOKEN);
    assert_eq!(r.status, 403);
    assert!(r.text().contains("worker token cannot act as a client"));
    assert!(r.header("set-cookie").is_none());
    assert_eq!(form("nope").status, 401);
    let r = form(CLIENT_TOKEN);
    assert_eq!(r.status, 303);
    let cookie = r.header("set-cookie").unwrap();
    assert!(
        cookie.contains("HttpOnly") && cookie.contains("SameSite=Strict"),
        "{cookie}"
    );
    assert!(
        !cookie.contains("Secure"),
        "plain HTTP cookie marked Secure: {cookie}"
    );
    let pair = cookie.split(';').next().unwrap().to_string();
    assert_eq!(dash.get("/api/jobs", Auth::Cookie(&pair)).status, 200);
    let page = dash.get("/", Auth::Cookie(&pair));
    assert_eq!(page.status, 200);
    assert!(page.text().contains("/assets/app.js"));
    assert_json_error(
        &dash.get("/api/jobs", Auth::Cookie("crease_token=dash-worker-token")),
        403,
    );
}

#[test]
fn with_tls_the_dashboard_is_https_only_and_its_cookie_is_secure() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let port = free_port();
    let (_c, ca) = start_tls(d, port);
    let https = Dash {
        addr: format!("127.0.0.1:{port}"),
        ca: Some(ca),
    };
    let r = https.get("/api/jobs", Auth::Bearer(CLIENT_TOKEN));
    assert_eq!(r.status, 200, "{}", r.text());
    assert_eq!(r.json()["jobs"].as_array().unwrap().len(), 0);
    assert_json_error(&https.get("/api/workers", Auth::Bearer(WORKER_TOKEN)), 403);
    let r = https.req(
        "POST",
        "/login",
        &[("Content-Type", "application/x-www-form-urlencoded")],
        format!("token={CLIENT_TOKEN}").as_bytes(),
    );
    assert_eq!(r.status, 303);
    assert!(r.header("set-cookie").unwrap().contains("; Secure"));
    // Plain HTTP to the same port gets no HTTP answer (the TLS handshake fails instead).
    let mut s = std::net::TcpStream::connect(format!("127.0.0.1:{port}")).unwrap();
    s.set_read_timeout(Some(std::time::Duration::from_secs(15)))
        .unwrap();
    use std::io::{Read, Write};
    s.write_all(b"GET /api/jobs HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        .unwrap();
    let mut got = Vec::new();
    let _ = s.read_to_end(&mut got);
    assert!(
        !String::from_utf8_lossy(&got).contains("HTTP/1.1 200"),
        "plain HTTP was served: {}",
        String::from_utf8_lossy(&got)
    );
}
