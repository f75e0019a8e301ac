// The student's view of one assignment (web/assignment.html, served at /assignments/{id}; docs/assignments.md):
// the brief, "Start from the starter scene", Check and Submit, and their submissions with the feedback the
// policy allows, each followed live while it is graded. The link's token is this page's identity (session.js)
// and becomes the workspace's too (api.js tokens.setStudent), so the renders the student makes in the
// workspace are theirs on this assignment, as the server treats a roster token as a job's owner.
import { ApiError, request } from "../api.js";
import { keptText } from "../editor.js";
import { encodeScene, MAX_LINK } from "../share.js";
import { formatJSON } from "../jsonpos.js";
import { $, benignError, h, store } from "../util.js";
import { scoreWhen, showBrief } from "./brief.js";
import { HandIn } from "./handin.js";
import { assignmentId, forget, join, keep, linkToken, studentApi } from "./session.js";
import { SubmissionList } from "./submissions.js";
import { setWorkingOn, useIdentity } from "./working.js";

const status = $("#a-status");
function say(kind, ...content) {
  status.hidden = !content.length;
  status.dataset.kind = kind;
  status.replaceChildren(...content);
}
window.addEventListener(
  "error",
  (e) => benignError(e) || say("error", `Something went wrong on this page: ${e.message}`),
);
window.addEventListener("unhandledrejection", (e) =>
  say("error", `Something went wrong on this page: ${e.reason?.message || e.reason}`),
);

const aid = assignmentId();
let stopCountdown = () => {};
let list = null;
let handin = null;

/** No token, or one the server does not take: say why, and offer joining by name (an open assignment). */
function noAccess(why) {
  say("", "");
  $("#a-brief").hidden = true;
  $("#a-work").hidden = true;
  $("#a-access").hidden = false;
  $("#a-access-why").replaceChildren(...why);
  document.body.dataset.access = "none";
}

async function open(token, { joined = null } = {}) {
  const api = studentApi(aid, token);
  let brief;
  try {
    brief = await api.brief();
  } catch (err) {
    if (err instanceof ApiError && err.status === 404) {
      forget(aid);
      noAccess([
        "The server does not know this link: either there is no such assignment, or its token is not one of its students'. ",
        "A link stops working when your instructor replaces it (a lost link gets a new one). Open the link in your latest email from your instructor, or ask them for a new one.",
      ]);
      return;
    }
    say(
      "error",
      `Could not open the assignment: ${err.message}. `,
      h("button", { type: "button", onclick: () => location.reload() }, "Try again"),
    );
    return;
  }
  if (!brief.student) {
    // everyone is the instructor on a server without an instructor token (loopback): this is not a student's link
    noAccess([
      "This is the instructor's view of the assignment, not a student's: a student's link carries their own token (#token=… from the roster).",
    ]);
    return;
  }
  useIdentity(token); // the workspace's "my jobs" are this student's from now on
  say("", "");
  $("#a-access").hidden = true;
  const briefRoot = $("#a-brief");
  briefRoot.hidden = false;
  $("#a-work").hidden = false;
  document.body.dataset.access = "student";
  if (joined) {
    const field = h("input", {
      type: "text",
      readonly: true,
      value: joined.link,
      class: "share-link",
      id: "a-own-link",
      "aria-label": "your personal link",
    });
    say(
      "warn",
      h(
        "span",
        {},
        `You joined as ${joined.name}. Keep your personal link to come back from another browser (it is shown this once): `,
      ),
      field,
    );
  }
  stopCountdown();
  stopCountdown = showBrief(briefRoot, brief, token, { onPhase: () => refreshBrief(api) });
  await startLink(brief);

  const ctx = {
    aid,
    token,
    api,
    compareBox: $("#compare"),
    scoreWhen: scoreWhen(brief.feedback),
    onFinal: () => {
      list.load();
      refreshBrief(api);
    },
  };
  if (!handin)
    handin = new HandIn($("#a-handin"), {
      aid,
      api,
      starter: brief.starter,
      onSubmitted: (view) => {
        list.add(view);
        refreshBrief(api);
      },
    });
  list?.close();
  list = new SubmissionList($("#a-sub-list"), $("#a-attempts"), $("#a-subs-status"), ctx);
  await list.load();
  document.body.dataset.ready = "true";
}

let briefAsked = 0;

async function refreshBrief(api) {
  // reads overlap (a submission's, then its grade's, a countdown's): only the latest asked is shown. The
  // submission's read answered after its grade's would show the attempt it held as used ("2 left" after an
  // invalid one), until the next read.
  const asked = ++briefAsked;
  try {
    const brief = await api.brief();
    if (asked !== briefAsked) return;
    stopCountdown();
    stopCountdown = showBrief($("#a-brief"), brief, api.token, { onPhase: () => refreshBrief(api) });
  } catch {
    // the last brief shown stays
  }
}

/** "Start from the starter scene": the workspace opens it from a link (#scene/<data>), with a way back here. A
 * scene the student built or changed in the workspace's editor is replaced only once they say so (Replace). */
async function startLink(brief) {
  const a = $("#a-start");
  a.hidden = !brief.starter;
  $("#a-start-ask").hidden = true;
  if (!brief.starter) return;
  const data = await encodeScene(JSON.stringify(brief.starter));
  a.href = `/#scene/${data}`;
  if (a.href.length > MAX_LINK) a.href = "/"; // too long for a link: handed over through the editor's kept text below
  const go = () => {
    setWorkingOn(aid, brief.name);
    if (a.getAttribute("href") === "/") store.set("rt.editor.text", formatJSON(brief.starter)); // the editor's kept text (editor.js KEY)
  };
  $("#a-start-replace").onclick = () => {
    go();
    location.assign(a.href);
  };
  $("#a-start-cancel").onclick = () => {
    $("#a-start-ask").hidden = true;
    a.focus();
  };
  a.onclick = async (e) => {
    if (e.button !== 0 || e.ctrlKey || e.metaKey || e.shiftKey || e.altKey) return go(); // a new tab or window: the link as it is
    e.preventDefault();
    if (!(await builtScene(brief.starter))) return $("#a-start-replace").click();
    $("#a-start-ask").hidden = false;
    $("#a-start-cancel").focus();
  };
}

/** Whether the workspace's editor holds a scene the student built or changed: not when it is empty, the
 * starter, or an example as the workspace loaded it (editor.js keeps the example's name). */
async function builtScene(starter) {
  const text = keptText();
  if (text === null || !text.trim()) return false;
  let value;
  try {
    value = JSON.parse(text);
  } catch {
    return true; // text that is not JSON (yet): the student's typing
  }
  const same = (scene) => JSON.stringify(scene) === JSON.stringify(value);
  if (same(starter)) return false;
  const name = store.get("rt.editor.name", null); // (editor.js NAME_KEY)
  if (typeof name !== "string" || !/^[A-Za-z0-9_-]+$/.test(name)) return true;
  try {
    return !same(await request("GET", `/api/scenes/${encodeURIComponent(name)}`, undefined, { token: null }));
  } catch {
    return true; // not an example (a file's name, a link's scene)
  }
}

$("#a-join").addEventListener("submit", async (e) => {
  e.preventDefault();
  const out = $("#a-join-status");
  const name = $("#a-join-name").value.trim();
  if (!name) {
    out.textContent = "Type your name first.";
    return;
  }
  out.textContent = "Joining…";
  let joined;
  try {
    joined = await join(aid, name);
  } catch (err) {
    out.textContent =
      err instanceof ApiError && err.status === 404
        ? "This assignment is not open to join by name: open the personal link your instructor sent you."
        : `Could not join: ${err.message}`;
    return;
  }
  out.textContent = "";
  keep(aid, joined.token);
  await open(joined.token, { joined });
});

async function start() {
  if (!aid || !/^[0-9a-f]{32}$/.test(aid)) {
    noAccess([
      "This address does not name an assignment: an assignment's link is /assignments/<its id>#token=<yours>.",
    ]);
    return;
  }
  const { token } = linkToken(aid);
  if (!token) {
    noAccess([
      "This page shows your brief, your checks and your submissions when it is opened with your personal link (the one your instructor mailed you, ending in #token=…). ",
      "Open that link once in this browser and it remembers you here.",
    ]);
    return;
  }
  if (window.self !== window.top) framed(token);
  await open(token);
}

/** Inside an LMS's frame: the page works there with its token (no cookie needed); where the frame is too small
 * or the browser keeps nothing for framed pages, the same page opens in a window of its own. */
function framed(token) {
  const link = h(
    "a",
    {
      href: `${location.pathname}#token=${encodeURIComponent(token)}`,
      target: "_blank",
      rel: "noopener",
      id: "a-new-window",
    },
    "Open in a new window",
  );
  document
    .querySelector("main")
    ?.prepend(h("p", { class: "hint", id: "a-framed" }, "Opened from your course's LMS. ", link));
}

// a link followed while this page is open (only its fragment changes: no new page): start again with its token
window.addEventListener("hashchange", () => {
  if (new URLSearchParams(location.hash.slice(1)).get("token")) location.reload();
});
start().finally(() => (document.body.dataset.ready = "true"));
