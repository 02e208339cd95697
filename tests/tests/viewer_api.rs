//! The 3D viewer's data over HTTP, from both mounts of the one handler: a coordinator's dashboard (behind its
//! client tokens) and `crease view` on a local folder. Frames decode to the very positions of the output and
//! input files; only fixed names are served; a job still running shows its input alone; `crease view`
//! refuses what it cannot show, and `--open` starts the browser `$BROWSER` names or says it could not.

mod dashboard_support;
mod viewer_support;

use crease_core::mesh::io::open_sequence;
use crease_dashboard::viewer::frame_buffer::decode;
use crease_e2e::*;
use dashboard_support::*;
use serde_json::Value;
use std::path::Path;
use std::process::Command;
use viewer_support::view;

const CLIENT: Auth = Auth::Bearer(CLIENT_TOKEN);

/// The positions of frame `t` of the sequence at `dir`, relative to `origin`, as the viewer sends them.
fn sent_positions(dir: &Path, t: usize, origin: &Value) -> Vec<f32> {
    let o: Vec<f64> = (0..3).map(|k| origin[k].as_f64().unwrap()).collect();
    open_sequence(dir)
        .unwrap()
        .source
        .read_frame(t)
        .unwrap()
        .iter()
        .flat_map(|p| [0, 1, 2].map(|k| (p[k] - o[k]) as f32))
        .collect()
}

/// Frame `t` over HTTP decodes to the input's and the output's positions, with overlays of the right sizes.
fn check_frame(
    get: impl Fn(&str) -> (u16, Vec<u8>),
    meta: &Value,
    input: &Path,
    output: &Path,
    t: usize,
) {
    let (status, body) = get(&format!("frame-{t}.bin"));
    assert_eq!(status, 200);
    let f = decode(&body).unwrap();
    assert_eq!(f.frame as usize, t);
    assert_eq!(f.input.unwrap(), sent_positions(input, t, &meta["origin"]));
    assert_eq!(
        f.output.unwrap(),
        sent_positions(output, t, &meta["origin"])
    );
    assert_eq!(f.displacement.unwrap().len(), f.n_vertices);
    assert_eq!(f.stretch.unwrap().len(), f.n_triangles);
}

#[test]
fn a_jobs_viewer_data_is_served_behind_the_dashboards_tokens() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let port = free_port();
    let c = start(d, port, &[]);
    let dash = Dash {
        addr: format!("127.0.0.1:{port}"),
        ca: None,
    };
    let (file, out) = job(d, "viewed");
    let id = c.submit(&file);
    let base = format!("/api/jobs/{id}/view/");
    let get = |name: &str| {
        let r = dash.get(&format!("{base}{name}"), CLIENT);
        (r.status, r.body)
    };

    // Queued (no worker yet): the input is shown alone, and the page is told why.
    let meta = dash.get(&format!("{base}meta.json"), CLIENT).json();
    assert!(meta["output"].is_null(), "{meta}");
    assert_eq!(meta["frames"], 4);
    assert!(meta["notes"].to_string().contains("not complete"), "{meta}");
    let f = decode(&get("frame-1.bin").1).unwrap();
    assert!(f.input.is_some() && f.output.is_none() && f.stretch.is_none());
    assert_eq!(get("report.json").0, 404);

    let _w = c.worker("w-viewer", &[]);
    c.wait_state(&id, &["done"]);
    let meta = dash.get(&format!("{base}meta.json"), CLIENT).json();
    assert!(meta["output"].is_object(), "{meta}");
    assert_eq!(meta["overlays"]["stretch"], true);
    assert_eq!(meta["overlays"]["anchors"], true);
    assert_eq!(
        meta["anchors"]["per_frame"],
        serde_json::json!([40, 40, 40, 40])
    );
    let triangles = meta["triangles"].as_u64().unwrap() as usize;
    let (status, index) = get("index.bin");
    assert_eq!(status, 200);
    assert_eq!(index.len(), 12 * triangles);
    for t in [0, 3] {
        check_frame(get, &meta, &fixture(), &out, t);
    }
    let (status, report) = get("report.json");
    assert_eq!(status, 200);
    assert_eq!(report, std::fs::read(out.join("report.json")).unwrap());
    assert_eq!(get("eval.json").0, 404);
    let past = dash.get(&format!("{base}frame-4.bin"), CLIENT);
    assert_eq!(past.status, 404);
    assert!(past.text().contains("past the end"), "{}", past.text());

    // The dashboard's tokens guard every viewer name; the worker token is not a client's.
    for name in ["meta.json", "index.bin", "frame-0.bin", "report.json"] {
        let path = format!("{base}{name}");
        assert_eq!(dash.get(&path, Auth::None).status, 401, "{name}");
        assert_eq!(
            dash.get(&path, Auth::Bearer(WORKER_TOKEN)).status,
            403,
            "{name}"
        );
    }
    // Fixed names only: nothing else under the output, and no way out of it.
    for name in [
        "anchors.json",
        "preview.png",
        "..%2freport.json",
        "..%2F..%2Fetc%2Fpasswd",
        ".crease-work%2Ffolds%2Fanchors.bin",
        "frame-1.bin%2F..",
        "frame-x.bin",
        "frame-99999999999.bin",
    ] {
        let r = dash.get(&format!("{base}{name}"), CLIENT);
        assert_eq!(r.status, 404, "{name}: {}", r.text());
    }
    for bad_id in ["job-nope", "..", "a%2Fb"] {
        let r = dash.get(&format!("/api/jobs/{bad_id}/view/meta.json"), CLIENT);
        assert_eq!(r.status, 404, "{bad_id}: {}", r.text());
    }
    // The page's modules and the vendored three.js are assets like the others (no token needed, no data).
    for asset in [
        "viewer.js",
        "frames.js",
        "report.js",
        "plot.js",
        "dom.js",
        "three.min.js",
    ] {
        let r = dash.get(&format!("/assets/{asset}"), Auth::None);
        assert_eq!(r.status, 200, "{asset}");
        assert!(r
            .header("content-type")
            .unwrap()
            .starts_with("text/javascript"));
    }
    let three = dash.get("/assets/three.min.js", Auth::None);
    assert!(three.text().contains("OrbitControls") && three.body.len() > 500_000);
}

#[test]
fn with_tls_the_viewer_is_served_over_https_behind_the_tokens() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let port = free_port();
    let (mut c, ca) = start_tls(d, port);
    c.scheme = "https";
    c.client_args
        .extend(["--tls-ca".to_string(), ca.display().to_string()]);
    let (file, _) = job(d, "over-tls");
    let id = c.submit(&file);
    let https = Dash {
        addr: format!("127.0.0.1:{port}"),
        ca: Some(ca),
    };
    let base = format!("/api/jobs/{id}/view/");
    let meta = https.get(&format!("{base}meta.json"), CLIENT);
    assert_eq!(meta.status, 200, "{}", meta.text());
    assert_eq!(meta.json()["frames"], 4);
    let f = decode(&https.get(&format!("{base}frame-0.bin"), CLIENT).body).unwrap();
    assert_eq!(f.input.unwrap().len(), 3 * f.n_vertices);
    assert_eq!(
        https.get(&format!("{base}frame-0.bin"), Auth::None).status,
        401
    );
}

#[test]
fn crease_view_serves_an_output_folder_and_an_input_alone() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let anchors = d.join("anchors.json");
    write_anchors(&anchors);
    let out = d.join("out");
    local_run(&fixture(), &anchors, &out, "fused", "1");
    let v = view(&out, &[]);
    let dash = Dash {
        addr: v.addr.clone(),
        ca: None,
    };
    let page = dash.get("/", Auth::None);
    assert_eq!(page.status, 200);
    assert!(page.text().contains(r#"<body data-mode="local">"#));
    assert!(v.url.ends_with("/#/view/local"), "{}", v.url);
    let base = "/api/jobs/local/view/";
    let meta = dash.get(&format!("{base}meta.json"), Auth::None).json();
    assert_eq!(meta["name"], "out");
    assert_eq!(meta["frames"], 4);
    let input_path = meta["input"]["path"].as_str().unwrap();
    assert_eq!(
        std::fs::canonicalize(input_path).unwrap(),
        std::fs::canonicalize(fixture()).unwrap()
    );
    let get = |name: &str| {
        let r = dash.get(&format!("{base}{name}"), Auth::None);
        (r.status, r.body)
    };
    check_frame(get, &meta, &fixture(), &out, 2);
    assert_eq!(
        get("report.json").1,
        std::fs::read(out.join("report.json")).unwrap()
    );
    // Only the viewer is mounted: no queue, no other id.
    assert_eq!(dash.get("/api/jobs", Auth::None).status, 404);
    assert_eq!(
        dash.get("/api/jobs/job-00001/view/meta.json", Auth::None)
            .status,
        404
    );
    drop(v);

    // An input folder alone: one sequence, no report.
    let v = view(&fixture(), &[]);
    let dash = Dash {
        addr: v.addr.clone(),
        ca: None,
    };
    let meta = dash.get(&format!("{base}meta.json"), Auth::None).json();
    assert!(
        meta["output"].is_null() && meta["input"].is_object(),
        "{meta}"
    );
    assert_eq!(meta["overlays"]["stretch"], false);
    let f = decode(&dash.get(&format!("{base}frame-3.bin"), Auth::None).body).unwrap();
    assert!(f.input.is_some() && f.output.is_none());
    assert_eq!(
        dash.get(&format!("{base}report.json"), Auth::None).status,
        404
    );
    drop(v);

    // --input names the input when the report's is gone: an output folder moved elsewhere still compares.
    let moved = d.join("moved-input");
    std::fs::create_dir(&moved).unwrap();
    for e in std::fs::read_dir(fixture()).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), moved.join(e.file_name())).unwrap();
    }
    let v = view(&out, &["--input", moved.to_str().unwrap()]);
    let dash = Dash {
        addr: v.addr.clone(),
        ca: None,
    };
    let meta = dash.get(&format!("{base}meta.json"), Auth::None).json();
    assert_eq!(meta["input"]["path"], moved.display().to_string());
}

#[test]
fn crease_view_refuses_what_it_cannot_show_and_opens_the_browser_it_is_given() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = |args: &[&str], env: &[(&str, &str)]| {
        let mut cmd = Command::new(bin());
        cmd.arg("view").args(args);
        for (k, v) in env {
            cmd.env(k, v);
        }
        cmd.output().unwrap()
    };
    let missing = d.join("nowhere");
    let o = run(&[missing.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("nowhere") && stderr(&o).contains("does not exist"),
        "{}",
        stderr(&o)
    );
    let empty = d.join("empty");
    std::fs::create_dir(&empty).unwrap();
    std::fs::write(empty.join("notes.txt"), "not a frame").unwrap();
    let o = run(&[empty.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("neither a crease output") && stderr(&o).contains("notes.txt"),
        "{}",
        stderr(&o)
    );
    let o = run(
        &[fixture().to_str().unwrap(), "--listen", "127.0.0.1:nope"],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));

    // --open: $BROWSER is run with the URL.
    let opened = d.join("opened-url");
    let script = d.join("browser.sh");
    std::fs::write(
        &script,
        format!("#!/bin/sh\necho \"$1\" > {}\n", opened.display()),
    )
    .unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let browser = script.to_str().unwrap().to_string();
    let port = free_port();
    let listen = format!("127.0.0.1:{port}");
    let mut child = Proc(
        Command::new(bin())
            .args([
                "view",
                fixture().to_str().unwrap(),
                "--open",
                "--listen",
                &listen,
            ])
            .env("BROWSER", &browser)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap(),
    );
    wait_until("the browser script to run", || {
        std::fs::read_to_string(&opened).is_ok_and(|s| s.contains("/#/view/local"))
    });
    assert_eq!(
        std::fs::read_to_string(&opened).unwrap().trim(),
        format!("http://{listen}/#/view/local")
    );
    child.kill();

    // No launcher at all: a clear error with the URL, not a silent server.
    let no_path = d.join("no-bin");
    std::fs::create_dir(&no_path).unwrap();
    let o = run(
        &[fixture().to_str().unwrap(), "--open"],
        &[
            ("BROWSER", "/nonexistent/browser"),
            ("PATH", no_path.to_str().unwrap()),
        ],
    );
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("no browser could be started")
            && e.contains("/nonexistent/browser (not found)")
            && e.contains("xdg-open (not found)")
            && e.contains("http://127.0.0.1:"),
        "{e}"
    );
}
