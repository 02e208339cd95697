// crease dashboard: renders the JSON API (/api/...) and stays current through one server-sent event stream
// (/api/events). No polling: a view is redrawn when an event says something changed. All text from the
// server is inserted as text (textContent), never as HTML.
import { el } from "/assets/dom.js";

const STATES = ["all", "queued", "running", "waiting", "done", "failed", "cancelled"];
const TERMINAL = new Set(["done", "failed", "cancelled"]);
const state = { jobs: new Map(), workers: [], filter: "all", job: null, refetch: null };
// `crease view` serves this page for one local folder: no queue, no live updates.
const LOCAL = document.body.dataset.mode === "local";

function fmtTime(unix) {
  return unix > 0 ? new Date(unix * 1000).toLocaleString() : "";
}

function fmtSecs(s) {
  if (!(s >= 0)) return "";
  if (s < 60) return s.toFixed(1) + " s";
  const m = Math.floor(s / 60), r = Math.round(s % 60);
  if (m < 60) return `${m} min ${r} s`;
  return `${Math.floor(m / 60)} h ${m % 60} min`;
}

function problem(msg) {
  const p = document.getElementById("problem");
  p.textContent = msg || "";
  p.hidden = !msg;
}

async function api(path, method) {
  const r = await fetch(path, {
    method: method || "GET",
    credentials: "same-origin",
    headers: { "Accept": "application/json" },
  });
  if (r.status === 401) {
    location.href = "/login";
    throw new Error("not signed in");
  }
  const body = await r.json().catch(() => ({ error: `HTTP ${r.status}` }));
  if (!r.ok) throw new Error(body.error || `HTTP ${r.status}`);
  return body;
}

// Stacked progress bar: done / running / failed over the job's total tasks (CueWeb style).
function progressBar(t) {
  const total = Math.max(t.total, 1);
  const pct = (n) => (100 * n / total).toFixed(2) + "%";
  const bar = el("div", {
    class: "bar",
    "data-done": String(t.done),
    "data-total": String(t.total),
    title: `${t.done} done, ${t.running} running, ${t.failed} failed, ${t.queued} queued of ${t.total}`,
  });
  for (const [k, n] of [["done", t.done], ["running", t.running], ["failed", t.failed]]) {
    const seg = el("span", { class: "seg " + k });
    seg.style.width = pct(n);
    bar.append(seg);
  }
  return el("div", { class: "progress" }, bar,
    el("span", { class: "count", text: `${t.done}/${t.total}` + (t.running ? ` · ${t.running} running` : "") + (t.failed ? ` · ${t.failed} dead` : "") }));
}

function stateBadge(s) {
  return el("span", { class: "state state-" + s, text: s });
}

function actionButtons(job) {
  const box = el("span", { class: "actions" });
  if (!TERMINAL.has(job.state)) {
    box.append(el("button", {
      class: "cancel", text: "Cancel", "data-action": "cancel",
      onclick: async (ev) => {
        ev.preventDefault();
        if (!confirm(`Cancel job ${job.name} (${job.id})?`)) return;
        try { await api(`/api/jobs/${encodeURIComponent(job.id)}/cancel`, "POST"); problem(""); }
        catch (e) { problem(`cancel ${job.id}: ${e.message}`); }
      },
    }));
  } else {
    box.append(el("button", {
      class: "resubmit", text: "Resubmit", "data-action": "resubmit",
      onclick: async (ev) => {
        ev.preventDefault();
        try {
          const r = await api(`/api/jobs/${encodeURIComponent(job.id)}/resubmit`, "POST");
          problem("");
          location.hash = `#/jobs/${r.id}`;
        } catch (e) { problem(`resubmit ${job.id}: ${e.message}`); }
      },
    }));
  }
  return box;
}

// ---------------------------------------------------------------- jobs list

function jobRow(j) {
  return el("tr", { "data-job": j.id, "data-state": j.state },
    el("td", {}, el("a", { href: `#/jobs/${j.id}`, text: j.name }), el("div", { class: "id", text: j.id })),
    el("td", {}, stateBadge(j.state)),
    el("td", { class: "num", text: String(j.priority) }),
    el("td", {}, progressBar(j.tasks)),
    el("td", { text: fmtTime(j.submitted_unix) }),
    el("td", { class: "num", text: fmtSecs(j.duration_secs) }),
    el("td", {}, actionButtons(j)));
}

function renderJobs() {
  const view = document.getElementById("view");
  const filters = el("div", { class: "filters" }, el("span", { text: "State:" }));
  for (const s of STATES) {
    const n = s === "all" ? state.jobs.size : [...state.jobs.values()].filter((j) => j.state === s).length;
    filters.append(el("button", {
      id: "filter-" + s,
      class: s === state.filter ? "filter on" : "filter",
      text: `${s} (${n})`,
      onclick: () => { state.filter = s; renderJobs(); },
    }));
  }
  const rows = [...state.jobs.values()]
    .filter((j) => state.filter === "all" || j.state === state.filter)
    .sort((a, b) => b.submitted_unix - a.submitted_unix || b.id.localeCompare(a.id));
  const body = el("tbody", {}, ...rows.map(jobRow));
  if (!rows.length) body.append(el("tr", {}, el("td", { colSpan: 7, class: "empty", text: "no jobs" })));
  const table = el("table", { id: "jobs" },
    el("thead", {}, el("tr", {}, ...["Job", "State", "Priority", "Progress", "Submitted", "Duration", ""].map((h) => el("th", { text: h })))),
    body);
  view.replaceChildren(el("h1", { text: "Jobs" }), filters, table);
}

// ---------------------------------------------------------------- one job

function kv(rows) {
  return el("table", { class: "kv" }, el("tbody", {}, ...rows.map(([k, v]) =>
    el("tr", {}, el("th", { text: k }), el("td", {}, v instanceof Node ? v : String(v ?? ""))))));
}

function attemptLog(a) {
  const head = `attempt ${a.attempt} · ${a.worker || "?"} · ${a.outcome || "running"}` +
    (a.finished_unix > 0 && a.started_unix > 0 ? ` · ${fmtSecs(a.finished_unix - a.started_unix)}` : "");
  return el("div", { class: "attempt" },
    el("div", { class: "attempt-head", text: head }),
    a.error ? el("div", { class: "error", text: a.error }) : null,
    el("pre", { class: "log", text: a.lines.join("\n") || "(no log lines)" }));
}

function stageSection(st) {
  const rows = [];
  for (const t of st.tasks) {
    rows.push(el("tr", { "data-task": t.key, "data-state": t.state },
      el("td", { class: "key", text: t.key }),
      el("td", {}, stateBadge(t.state)),
      el("td", { class: "num", text: String(t.attempts) }),
      el("td", { text: t.worker }),
      el("td", { class: "num", text: t.work_secs > 0 ? fmtSecs(t.work_secs) : "" }),
      el("td", {}, t.logs.length
        ? el("details", { class: "logs" }, el("summary", { text: `${t.logs.length} attempt log${t.logs.length > 1 ? "s" : ""}` }), ...t.logs.map(attemptLog))
        : el("span", { class: "muted", text: "—" }),
        t.last_error ? el("div", { class: "error", text: t.last_error }) : null)));
  }
  const c = st.counts;
  return el("section", { class: "stage", "data-stage": st.kind },
    el("h3", {}, document.createTextNode(st.label + " "), el("span", { class: "muted", text: `${c.done}/${c.total} done` + (c.running ? `, ${c.running} running` : "") + (c.failed ? `, ${c.failed} failed` : "") })),
    el("table", { class: "tasks" },
      el("thead", {}, el("tr", {}, ...["Task", "State", "Attempts", "Worker", "Work time", "Log"].map((h) => el("th", { text: h })))),
      el("tbody", {}, ...rows)));
}

function renderJob(j) {
  const view = document.getElementById("view");
  // Keep open log panes open across live redraws.
  const open = new Set([...view.querySelectorAll("tr[data-task] details[open]")].map((d) => d.closest("tr").dataset.task));
  const images = el("div", { class: "images" }, ...j.files.map((f) =>
    el("figure", { "data-file": f.name },
      el("a", { href: f.url, target: "_blank", rel: "noopener" }, el("img", { src: f.url + "?t=" + (j.finished_unix || 0), alt: f.label })),
      el("figcaption", { text: `${f.label} (${f.name})` }))));
  const parts = [
    el("p", {}, el("a", { href: "#/", text: "← Jobs" })),
    el("h1", {}, document.createTextNode(j.name + " "), stateBadge(j.state)),
    el("div", { class: "jobhead", id: "job", "data-job": j.id, "data-state": j.state },
      kv([["id", j.id], ["priority", j.priority], ["progress", progressBar(j.tasks)], ["submitted", fmtTime(j.submitted_unix)],
        ["finished", fmtTime(j.finished_unix)], ["duration", fmtSecs(j.duration_secs)], ["work time", fmtSecs(j.work_secs)],
        ["output", j.output], ["message", j.message]]),
      actionButtons(j)),
  ];
  const p = panelsFor(j.id, `${j.id}:${j.finished_unix || 0}:${j.report ? "report" : "none"}`, !!j.report);
  parts.push(el("h2", { text: "Viewer" }), p.viewerBox);
  if (j.files.length) parts.push(el("h2", { text: "Pictures" }), images);
  parts.push(el("h2", { text: "Report" }), p.reportBox);
  parts.push(el("h2", { text: "Tasks by stage" }), ...j.stages.map(stageSection));
  view.replaceChildren(...parts);
  for (const key of open) {
    const d = view.querySelector(`tr[data-task="${CSS.escape(key)}"] details`);
    if (d) d.open = true;
  }
}

// ---------------------------------------------------------------- viewer and report panels

const viewBase = (id) => `/api/jobs/${encodeURIComponent(id)}/view/`;

// The viewer and report of the page shown, kept across live redraws (a WebGL canvas and its loaded frames
// are not rebuilt for every event) and replaced when the job's output changes.
const panels = { key: null, viewer: null, viewerBox: null, reportBox: null };

function closePanels() {
  if (panels.viewer) panels.viewer.destroy();
  Object.assign(panels, { key: null, viewer: null, viewerBox: null, reportBox: null });
}

function panelsFor(id, key, hasReport) {
  if (panels.key === key) return panels;
  closePanels();
  panels.key = key;
  panels.viewerBox = el("div", { id: "viewer", class: "viewer", "data-job": id });
  panels.reportBox = el("div", { class: "report-box" }, el("p", { class: "muted", text: "loading the report…" }));
  import("/assets/viewer.js")
    .then((m) => m.openViewer(panels.viewerBox, viewBase(id)))
    .then((v) => { if (panels.key === key) panels.viewer = v; else v.destroy(); }, () => { /* shown in the box */ });
  loadReport(id, key, panels.reportBox, hasReport);
  return panels;
}

// The report of the output: report.json and eval.json are fetched only when meta.json says they exist (or,
// when the viewer cannot open the output here, when the job page says the report exists).
async function loadReport(id, key, box, hasReport) {
  const base = viewBase(id);
  const orNull = (name) => api(base + name).catch(() => null);
  try {
    const meta = await orNull("meta.json");
    const files = meta ? meta.files : { "report.json": hasReport, "eval.json": false };
    const [m, r, e] = await Promise.all([import("/assets/report.js"),
      files["report.json"] ? orNull("report.json") : null, files["eval.json"] ? orNull("eval.json") : null]);
    if (panels.key !== key) return;
    box.replaceChildren(r || e ? m.renderReport(r, e, meta, base)
      : el("p", { class: "muted", id: "no-report", text: "No report.json yet: the report appears when the job is done." }));
  } catch (err) {
    if (panels.key === key) box.replaceChildren(el("p", { class: "error", text: `report: ${err.message}` }));
  }
}

// crease view: one local folder, no queue.
function renderLocal(id) {
  const view = document.getElementById("view");
  const p = panelsFor(id, `local:${id}`, false);
  const title = el("h1", { id: "local-title", text: "crease view" });
  api(viewBase(id) + "meta.json").then((m) => { title.textContent = m.name; }, (e) => problem(`${id}: ${e.message}`));
  view.replaceChildren(title, el("h2", { text: "Viewer" }), p.viewerBox, el("h2", { text: "Report" }), p.reportBox);
}

async function loadJob(id) {
  try {
    const j = await api(`/api/jobs/${encodeURIComponent(id)}`);
    if (state.job === id) { renderJob(j); problem(""); }
  } catch (e) {
    if (state.job === id) problem(`job ${id}: ${e.message}`);
  }
}

// ---------------------------------------------------------------- workers

function renderWorkers() {
  const view = document.getElementById("view");
  const rows = state.workers.map((w) => el("tr", { "data-worker": w.id, "data-draining": String(w.draining) },
    el("td", {}, document.createTextNode(w.name), el("div", { class: "id", text: `${w.id} · ${w.address}` })),
    el("td", { class: "num", text: `${w.running}/${w.capacity}` }),
    el("td", {}, ...w.tasks.map((t) => el("div", {}, el("a", { href: `#/jobs/${t.job_id}`, text: t.job_id }), document.createTextNode(` ${t.key} (attempt ${t.attempt})`)))),
    el("td", { class: "num", text: `${w.last_heartbeat_secs.toFixed(1)} s ago` }),
    el("td", {}, w.draining ? el("span", { class: "state state-waiting", text: "draining" }) : el("span", { class: "state state-done", text: "accepting" }))));
  if (!rows.length) rows.push(el("tr", {}, el("td", { colSpan: 5, class: "empty", text: "no workers registered" })));
  view.replaceChildren(el("h1", { text: "Workers" }),
    el("table", { id: "workers" },
      el("thead", {}, el("tr", {}, ...["Worker", "Running / capacity", "Tasks", "Last heartbeat", "Draining"].map((h) => el("th", { text: h })))),
      el("tbody", {}, ...rows)));
}

// ---------------------------------------------------------------- routing and live updates

function route() {
  const h = location.hash || "#/";
  if (LOCAL) {
    const m = h.match(/^#\/view\/([A-Za-z0-9_-]+)$/);
    renderLocal(m ? m[1] : "local");
    return;
  }
  const m = h.match(/^#\/jobs\/([A-Za-z0-9_-]+)$/);
  state.job = m ? m[1] : null;
  if (!m) closePanels();
  document.getElementById("nav-jobs").classList.toggle("on", !m && h !== "#/workers");
  document.getElementById("nav-workers").classList.toggle("on", h === "#/workers");
  if (m) loadJob(m[1]);
  else if (h === "#/workers") renderWorkers();
  else renderJobs();
}

function redraw() {
  const h = location.hash || "#/";
  if (state.job) return;
  if (h === "#/workers") renderWorkers(); else renderJobs();
}

function connect() {
  const live = document.getElementById("live");
  const es = new EventSource("/api/events");
  es.addEventListener("open", () => { live.textContent = "live"; live.className = "live on"; });
  es.addEventListener("error", () => {
    live.textContent = "reconnecting"; live.className = "live off";
    // The browser retries a dropped stream by itself but gives up on a refused one (signed out, coordinator
    // restarted with other tokens): find out which, once, and either go to the login form or reconnect.
    if (es.readyState === EventSource.CLOSED) {
      setTimeout(() => api("/api/workers").then(connect, (e) => problem(`live updates: ${e.message}`)), 3000);
    }
  });
  es.addEventListener("jobs", (ev) => {
    state.jobs = new Map(JSON.parse(ev.data).jobs.map((j) => [j.id, j]));
    redraw();
    if (state.job) loadJob(state.job);
  });
  es.addEventListener("job", (ev) => {
    const d = JSON.parse(ev.data);
    state.jobs.set(d.job.id, d.job);
    if (state.job === d.job.id) {
      // Several task events arrive together: fetch the job once for the lot.
      if (!state.refetch) state.refetch = setTimeout(() => { state.refetch = null; loadJob(d.job.id); }, 250);
    } else redraw();
  });
  es.addEventListener("workers", (ev) => {
    state.workers = JSON.parse(ev.data).workers;
    if ((location.hash || "#/") === "#/workers") renderWorkers();
  });
  es.addEventListener("problem", (ev) => problem(JSON.parse(ev.data).error));
}

window.addEventListener("hashchange", route);
// Module scripts run once the document is parsed: no need to wait for DOMContentLoaded.
route();
if (!LOCAL) connect();
