// "Working on <assignment>": the workspace's way back to the assignment a student started from. The
// assignment's page keeps {id, name} when its "Start from the starter scene" opens the workspace; the
// workspace shows a note with a link back until it is dismissed.
import { h, store } from "../util.js";

const KEY = "rt.course.working";

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
  const dismiss = h("button", { type: "button", class: "small", "aria-label": "Dismiss: I am not working on this assignment" }, "×");
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
