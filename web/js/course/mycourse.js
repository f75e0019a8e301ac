// A student's course page (web/mycourse.html, served at /courses/{id}): the link their course's roster gave
// (/courses/{id}#token=K) lists the assignments they are on, each opened with the same token (one identity
// across the course). The token is kept in this browser, as an assignment's page keeps its own, and taken out
// of the address bar at once.
import { request } from "../api.js";
import { $, h, store } from "../util.js";
import { keep } from "./session.js";

const cid = decodeURIComponent(/^\/courses\/([^/]+)\/?$/.exec(location.pathname)?.[1] || "");
const key = `rt.coursepage.${cid}.token`;
const status = $("#c-status");

function tokenOf() {
  const fromLink = new URLSearchParams(location.hash.slice(1)).get("token");
  if (location.hash) history.replaceState(null, "", location.pathname + location.search);
  if (fromLink) store.set(key, fromLink);
  return fromLink || store.get(key, null);
}

async function main() {
  const token = tokenOf();
  if (!token) {
    status.dataset.kind = "error";
    status.textContent = "This page needs your personal link (the one your instructor sent, or your LMS opened).";
    return;
  }
  try {
    const c = await request("GET", `/api/courses/${encodeURIComponent(cid)}`, undefined, { token, cache: "no-store" });
    document.title = `${c.name} · Ray tracing for teaching`;
    $("#c-name").textContent = c.name;
    status.dataset.kind = "ok";
    status.textContent = c.you?.name ? `Signed in as ${c.you.name}.` : "Signed in.";
    $("#c-assignments").replaceChildren(
      ...c.assignments.map((a) => {
        keep(a.id, token); // the assignment's page opens with it, no fragment needed
        return h(
          "li",
          {},
          h("a", { href: a.page }, a.name),
          h("span", { class: "muted" }, ` · due ${new Date(a.deadline).toLocaleString()}`),
        );
      }),
    );
    if (!c.assignments.length) $("#c-assignments").replaceChildren(h("li", { class: "muted" }, "No assignment yet."));
  } catch (err) {
    status.dataset.kind = "error";
    status.textContent =
      err.status === 404
        ? "This link does not open the course (it may have been replaced: ask your instructor for your new one)."
        : `Could not open the course: ${err.message}`;
  }
}

main();
