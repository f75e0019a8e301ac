// The instructor's course page (web/course.html, served at /course): the instructor's token (kept as the
// Grading tab keeps it), every assignment with the form that publishes one, and one assignment's dashboard
// at /course#<id> (web/js/course/instructor_board.js). Every request carries the instructor's token
// (`as: "instructor"`); on a server listening on loopback only without one, everyone is the instructor,
// and the page says so when the server answered without a token.
import { tokens } from "../api.js";
import { $, h } from "../util.js";
import { AssignmentForm } from "./instructor_form.js";
import { Board } from "./instructor_board.js";
import { course, say, tokenProblem, when } from "./instructor_util.js";

const view = $("#course-view");
const access = $("#course-access-status");
const tokenInput = $("#course-token");
let board = null;

/** The address's assignment and student: /course#<id> is the dashboard, /course#<id>/<student> with that
 * student's detail open. */
function fromHash() {
  const [id, student] = location.hash.slice(1).split("/").map((x) => decodeURIComponent(x || ""));
  return /^[0-9a-f]{32}$/.test(id) ? { id, student: student || null } : { id: null, student: null };
}

/** Say what the server's last answer tells of the token; true when it answered. */
function accessOk(err) {
  const problem = err ? tokenProblem(err, !!tokens.instructor()) : null;
  if (problem) {
    say(access, "error", problem);
    tokenInput.setAttribute("aria-invalid", "true");
    return false;
  }
  tokenInput.removeAttribute("aria-invalid");
  if (!err) {
    say(access, "ok", tokens.instructor() ? "Signed in as the instructor." : "This server has no instructor token and listens on loopback only: everyone who reaches it is the instructor (fine on your own machine; a class's server needs TRACER_INSTRUCTOR_TOKEN).");
  }
  return !err;
}

async function showList() {
  board?.close();
  board = null;
  document.title = "Course: assignments";
  $("#crumbs").replaceChildren();
  const list = h("ul", { class: "course-list", id: "assignment-list", "aria-live": "polite" });
  const form = new AssignmentForm({ onDone: (a) => (location.hash = a.id) });
  const note = h("p", { class: "hint", id: "list-status", role: "status" });
  view.replaceChildren(
    h(
      "div",
      { class: "course-home" },
      h("section", { class: "panel", "aria-labelledby": "h-list" }, h("div", { class: "panel-head" }, h("h2", { id: "h-list" }, "Assignments")), note, list),
      h(
        "section",
        { class: "panel", "aria-labelledby": "h-publish" },
        h("div", { class: "panel-head" }, h("h2", { id: "h-publish" }, "Publish an assignment")),
        h("p", { class: "hint" }, "A grading spec with a deadline and a policy; its reference renders as soon as it is published. The whole path, from spec to grades: ", h("a", { href: "/reference/assignments.md" }, "how assignments work"), "."),
        form.el,
      ),
    ),
  );
  try {
    const { assignments } = await course.list();
    accessOk(null);
    say(note, "ok", assignments.length ? `${assignments.length} assignment${assignments.length > 1 ? "s" : ""}, the newest last.` : "None yet: publish one with the form.");
    list.replaceChildren(
      ...assignments.map((a) =>
        h(
          "li",
          { dataset: { id: a.id } },
          h("a", { href: `#${a.id}` }, a.name),
          h("span", { class: "muted" }, ` · due ${when(a.deadline)} · ${a.students} student${a.students === 1 ? "" : "s"} · version ${a.version}`),
        ),
      ),
    );
  } catch (err) {
    accessOk(err);
    say(note, "error", `Could not list the assignments: ${err.message}`);
  }
}

async function route() {
  const { id, student } = fromHash();
  if (!id) return showList();
  if (board?.aid === id) {
    if (student && student !== board.open_) board.showStudent(student);
    return;
  }
  board?.close();
  board = new Board(id, view, { access: accessOk });
  await board.open(student);
}

tokenInput.value = tokens.instructor() || "";
tokenInput.addEventListener("change", () => {
  if (tokenInput.value.trim() === (tokens.instructor() || "")) return; // a second change event (on blur): nothing new
  tokens.setInstructor(tokenInput.value.trim());
  board?.close();
  board = null;
  route();
});
window.addEventListener("hashchange", route);
route().finally(() => (document.body.dataset.ready = "true"));
