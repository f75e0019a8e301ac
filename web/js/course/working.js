// "Working on <assignment>": the workspace's way back to the assignment a student started from. The
// assignment's page keeps {id, name} when its "Start from the starter scene" opens the workspace; the
// workspace shows a note with a link back until it is dismissed.
import { request, tokens } from "../api.js";
import { h, store } from "../util.js";

const KEY = "rt.course.working";
const IDENTITY_KEY = "rt.course.identity"; // the workspace's token, when an assignment's link set it
const ADOPTED_KEY = "rt.course.adopted"; // the identity whose jobs the workspace has listed already

/** Make a link's token the workspace's: its "my jobs" are this student's (the server owns jobs by token). */
export function useIdentity(token) {
  tokens.setStudent(token);
  store.set(IDENTITY_KEY, token);
}

/** The jobs this browser does not list yet of an identity an assignment's link brought (rendered in another
 * browser with the same link): once per identity, so a job forgotten from the list stays forgotten. */
export async function identityJobs() {
  const token = tokens.student();
  if (!token || store.get(IDENTITY_KEY, null) !== token || store.get(ADOPTED_KEY, null) === token) return [];
  const list = await request("GET", "/api/jobs?scope=mine&limit=20", undefined, { cache: "no-store" });
  store.set(ADOPTED_KEY, token);
  return list.jobs || [];
}

/** Remember that the workspace is being used for assignment `id` (named `name`). */
export function setWorkingOn(id, name) {
  store.set(KEY, { id, name });
}

/** Show the note in `el` (hidden when there is none). */
export function showWorkingOn(el) {
  const w = store.get(KEY, null);
  if (!w || typeof w.id !== "string" || !/^[0-9a-f]{32}$/.test(w.id)) {
    el.hidden = true;
    return;
  }
  const dismiss = h(
    "button",
    { type: "button", class: "small", "aria-label": "Dismiss: I am not working on this assignment" },
    "×",
  );
  dismiss.addEventListener("click", () => {
    store.set(KEY, null);
    el.hidden = true;
  });
  el.replaceChildren(
    h("span", {}, "Working on ", h("strong", {}, String(w.name || "an assignment")), " — "),
    h("a", { href: `/assignments/${w.id}`, id: "working-back" }, "back to the assignment"),
    h("span", { class: "muted" }, " (hand in the editor's scene there with “Take the workspace's scene”)"),
    dismiss,
  );
  el.hidden = false;
}
