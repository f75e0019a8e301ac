// The operator's status page (web/status.html, served at /status): GET /api/status with the admin's token (the
// instructor token, kept in this browser as /course keeps it), drawn for a person: the worker hosts and their
// workers, the queue by lane, the grades going back to the LMS, the last backup, the disk against its limit, the
// release and the schema. Each panel says in words whether all is well; it is read again every REFRESH_MS and on
// the Refresh button. What each fact means: docs/service.md, "The status page".
import { ApiError, request, tokens } from "./api.js";
import { $, h } from "./util.js";

const REFRESH_MS = 15000;
const view = $("#status-view");
const said = $("#status-said");
const tokenInput = $("#status-token");

const say = (kind, text) => {
  said.dataset.kind = kind;
  said.textContent = text;
};

/** What a refused request says of the token (null: not the token's fault). */
function tokenProblem(err, hasToken) {
  if (!(err instanceof ApiError)) return null;
  if (err.status === 403) return `The server has no admin: ${err.message}`;
  if (err.status === 401)
    return hasToken
      ? "The server refused this token: the status page is the server admin's (TRACER_INSTRUCTOR_TOKEN), not a course's staff."
      : "The server needs the admin's token (TRACER_INSTRUCTOR_TOKEN): enter it above.";
  return null;
}

/** Bytes as a person reads them (1.2 GB). */
export function bytes(n) {
  if (n === null || n === undefined) return "not measured yet";
  const units = ["bytes", "kB", "MB", "GB", "TB"];
  let i = 0;
  let x = n;
  while (x >= 1000 && i < units.length - 1) {
    x /= 1000;
    i += 1;
  }
  return i === 0 ? `${x} bytes` : `${x.toFixed(x < 10 ? 1 : 0)} ${units[i]}`;
}

/** A duration in seconds as words (3 h 20 min, 2 days 4 h). */
export function age(s) {
  if (s === null || s === undefined) return "never";
  if (s < 90) return `${Math.round(s)} s`;
  if (s < 5400) return `${Math.round(s / 60)} min`;
  if (s < 2 * 86400) return `${Math.floor(s / 3600)} h ${Math.round((s % 3600) / 60)} min`;
  return `${Math.floor(s / 86400)} days ${Math.round((s % 86400) / 3600)} h`;
}

const flag = (kind, text) => h("p", { class: "status-flag", "data-kind": kind }, text);
const panel = (id, title, ...body) =>
  h("section", { class: "panel", id, "aria-labelledby": `${id}-h` }, h("h2", { id: `${id}-h` }, title), ...body);
const table = (caption, head, rows) =>
  h(
    "table",
    {},
    h("caption", { class: "sr-only" }, caption),
    h(
      "thead",
      {},
      h(
        "tr",
        {},
        head.map(([text, num]) => h("th", { scope: "col", class: num ? "num" : "" }, text)),
      ),
    ),
    h(
      "tbody",
      {},
      rows.map((r) =>
        h(
          "tr",
          {},
          r.map((cell, i) =>
            h(i === 0 ? "th" : "td", i === 0 ? { scope: "row" } : { class: head[i][1] ? "num" : "" }, cell),
          ),
        ),
      ),
    ),
  );
const facts = (pairs) =>
  h(
    "dl",
    {},
    pairs.flatMap(([k, v]) => [h("dt", {}, k), h("dd", {}, v)]),
  );

function workersPanel(s) {
  const down = s.hosts.reduce((n, x) => n + (x.workers - x.alive), 0);
  const state =
    s.workers.length === 0
      ? flag(
          "error",
          s.backend === "redis"
            ? "No worker host is connected: nothing renders (start python -m server.worker)."
            : "No render worker runs on this host: nothing renders (TRACER_WORKERS).",
        )
      : down
        ? flag("warn", `${down} worker${down > 1 ? "s" : ""} not alive.`)
        : flag(
            "ok",
            `${s.workers.length} worker${s.workers.length > 1 ? "s" : ""} on ${s.hosts.length} host${s.hosts.length > 1 ? "s" : ""}, all alive.`,
          );
  return panel(
    "st-workers",
    "Workers and their hosts",
    state,
    s.hosts.length
      ? table(
          "Worker hosts",
          [["Host"], ["Workers", 1], ["Alive", 1], ["Rendering", 1], ["Devices"]],
          s.hosts.map((x) => [x.host, x.workers, x.alive, x.busy, x.devices.join(", ") || "?"]),
        )
      : null,
    h(
      "p",
      { class: "hint" },
      `Backend: ${s.backend === "redis" ? "Redis (worker hosts anywhere)" : "embedded (worker processes of this host)"}.`,
    ),
  );
}

function queuePanel(s) {
  const lanes = Object.entries(s.queue);
  const queued = lanes.reduce((n, [, v]) => n + v.queued, 0);
  return panel(
    "st-queue",
    "Queue by lane",
    flag(
      queued && !s.workers.length ? "error" : "ok",
      queued ? `${queued} job${queued > 1 ? "s" : ""} waiting.` : "Nothing waiting.",
    ),
    table(
      "Jobs by lane",
      [["Lane"], ["Waiting", 1], ["Rendering", 1]],
      lanes.map(([lane, v]) => [lane, v.queued, v.running]),
    ),
    h(
      "p",
      { class: "hint" },
      "Interactive: the page's renders and ray trees, taken first. Batch: long renders and grading.",
    ),
  );
}

function lmsPanel(s) {
  const l = s.lms;
  if (!l) return panel("st-lms", "Grades to the LMS", flag("warn", "LTI is not running on this server."));
  const state = l.failed
    ? flag("warn", `${l.failed} grade${l.failed > 1 ? "s" : ""} failed to post and will be tried again.`)
    : l.pending
      ? flag("ok", `${l.pending} grade${l.pending > 1 ? "s" : ""} about to be posted.`)
      : flag("ok", "Nothing waiting to be posted.");
  return panel(
    "st-lms",
    "Grades to the LMS",
    state,
    facts([
      ["Pending", String(l.pending)],
      ["Failed (pending again)", String(l.failed)],
      ["Sent", String(l.sent)],
      ["Oldest pending", l.oldest_pending_seconds === null ? "none" : `${age(l.oldest_pending_seconds)} ago`],
      ...(l.last_error
        ? [
            [
              "Last error",
              `${l.last_error.message} (platform ${l.last_error.platform_id}, ${l.last_error.tries} ${l.last_error.tries === 1 ? "try" : "tries"}; next ${new Date(l.last_error.next_try).toLocaleString()})`,
            ],
          ]
        : []),
    ]),
  );
}

function backupPanel(s) {
  const b = s.backup;
  const state = !b.time
    ? flag(
        "error",
        "No backup recorded: run python -m server backup (deploy/systemd/tracer-backup.timer does it nightly).",
      )
    : b.old
      ? flag("warn", `The last backup is ${age(b.age_seconds)} old: the nightly backup has not run.`)
      : flag("ok", `Last backup ${age(b.age_seconds)} ago.`);
  return panel(
    "st-backup",
    "Last backup",
    state,
    b.time
      ? facts([
          ["Taken", new Date(b.time).toLocaleString()],
          ["Age", age(b.age_seconds)],
          ["Where", b.dest || "?"],
          ["Size", bytes(b.bytes)],
        ])
      : null,
  );
}

function diskPanel(s) {
  const d = s.disk;
  const limit = d.limit_bytes ? bytes(d.limit_bytes) : "no limit (TRACER_MAX_DATA_BYTES=0)";
  const share = d.share === null ? null : Math.round(d.share * 100);
  const state =
    d.used_bytes === null
      ? flag("ok", "Not measured yet (the janitor's first round).")
      : d.near
        ? flag(
            "warn",
            `The data directory holds ${share}% of its limit: the janitor removes the oldest finished jobs past it.`,
          )
        : flag("ok", share === null ? `${bytes(d.used_bytes)} used.` : `${share}% of the limit used.`);
  return panel(
    "st-disk",
    "Disk",
    state,
    share === null
      ? null
      : h("meter", {
          class: "status-meter",
          min: "0",
          max: "100",
          value: String(Math.min(share, 100)),
          "aria-label": `Disk use: ${share}% of the limit`,
        }),
    facts([
      ["Data directory", bytes(d.used_bytes)],
      ["Limit", limit],
      ["Free on its disk", bytes(d.free_bytes)],
      ["Measured", d.measured_at ? new Date(d.measured_at).toLocaleString() : "not yet"],
    ]),
  );
}

function releasePanel(s) {
  const same = s.schema.version === s.schema.latest;
  return panel(
    "st-release",
    "Version and schema",
    flag(
      same ? "ok" : "error",
      same
        ? "The database's schema is this release's."
        : `The database's schema is ${s.schema.version}, this release's ${s.schema.latest}: run python -m server migrate.`,
    ),
    facts([
      ["Version", s.version],
      ["Schema", `${s.schema.version} (this release: ${s.schema.latest})`],
      ["Server time", new Date(s.time).toLocaleString()],
    ]),
  );
}

let asked = 0;

async function load() {
  // reads overlap (a token typed while the last read, with the old token, is in flight; the timer's; Refresh):
  // only the latest asked is shown, never the old token's refusal after the new token's status
  const mine = ++asked;
  say("busy", "Reading the server's status…");
  try {
    const s = await request("GET", "/api/status", undefined, { as: "instructor", cache: "no-store" });
    if (mine !== asked) return;
    view.replaceChildren(workersPanel(s), queuePanel(s), lmsPanel(s), backupPanel(s), diskPanel(s), releasePanel(s));
    tokenInput.removeAttribute("aria-invalid");
    say("ok", `Read at ${new Date().toLocaleTimeString()}; read again every ${REFRESH_MS / 1000} s.`);
  } catch (err) {
    if (mine !== asked) return;
    const problem = tokenProblem(err, !!tokens.instructor());
    if (problem) tokenInput.setAttribute("aria-invalid", "true");
    view.replaceChildren();
    say("error", problem || err.message);
  }
}

tokenInput.value = tokens.instructor() || "";
tokenInput.addEventListener("change", () => {
  tokens.setInstructor(tokenInput.value.trim());
  load();
});
$("#status-refresh").addEventListener("click", load);
setInterval(() => document.visibilityState === "visible" && load(), REFRESH_MS);
load();
