// The instructor's course page (web/course.html, served at /course): the instructor's token (kept as the
// Grading tab keeps it), every assignment with the form that publishes one, and one assignment's dashboard
// at /course#<id> (web/js/course/instructor_board.js). Every request carries the instructor's token
// (`as: "instructor"`); on a server listening on loopback only without one, everyone is the instructor,
// and the page says so when the server answered without a token.
import { tokens } from "../api.js";
import { $, h } from "../util.js";
import { AuditPanel } from "./audit.js";
import { AssignmentForm } from "./instructor_form.js";
import { Board } from "./instructor_board.js";
import { course, linkBox, say, tokenProblem, when } from "./instructor_util.js";

const view = $("#course-view");

// A staff link (/course#token=K, mailed by the admin, or /course#token=K&open=<id> from an LMS launch): the
// token becomes this browser's instructor token, and the address keeps only the assignment to open.
{
  const params = new URLSearchParams(location.hash.slice(1));
  if (params.get("token")) {
    tokens.setInstructor(params.get("token"));
    const open = params.get("open");
    history.replaceState(null, "", location.pathname + location.search + (open ? `#${encodeURIComponent(open)}` : ""));
  }
}
const access = $("#course-access-status");
const tokenInput = $("#course-token");
let board = null;
let signedAs = null; // "Signed in as a TA of ..." once the token's course and role are known
let madeCourse = null; // the course the admin just created: the publish form publishes into it

/** The token's field says whose token it is once the server told the role (a TA's page said "Instructor
 * token"). */
function showRole(role) {
  const label = document.querySelector('label[for="course-token"]');
  const words = { ta: "Your TA token", instructor: "Your instructor token" }[role];
  if (!label || !words) return;
  label.textContent = words;
  tokenInput.placeholder = "the token of your staff link";
  $("#course-token-help").textContent =
    "It came with the staff link you were sent (kept in this browser); open that link again to sign in anew.";
}

/** The address's assignment and student: /course#<id> is the dashboard, /course#<id>/<student> with that
 * student's detail open. */
function fromHash() {
  const [id, student] = location.hash
    .slice(1)
    .split("/")
    .map((x) => decodeURIComponent(x || ""));
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
    say(
      access,
      "ok",
      signedAs || tokens.instructor()
        ? signedAs || "Signed in as the server's admin (the instructor token)."
        : "This server has no instructor token and listens on loopback only: everyone who reaches it is the instructor (fine on your own machine; a class's server needs TRACER_INSTRUCTOR_TOKEN).",
    );
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
      h(
        "section",
        { class: "panel", "aria-labelledby": "h-list" },
        h("div", { class: "panel-head" }, h("h2", { id: "h-list" }, "Assignments")),
        note,
        list,
      ),
      h(
        "section",
        { class: "panel", "aria-labelledby": "h-publish" },
        h("div", { class: "panel-head" }, h("h2", { id: "h-publish" }, "Publish an assignment")),
        h(
          "p",
          { class: "hint" },
          "A grading spec with a deadline and a policy; its reference renders as soon as it is published. The whole path, from spec to grades: ",
          h("a", { href: "/reference/assignments.md" }, "how assignments work"),
          ".",
        ),
        form.el,
      ),
    ),
  );
  const courses = h(
    "section",
    { class: "panel", "aria-labelledby": "h-courses", id: "courses" },
    h("div", { class: "panel-head" }, h("h2", { id: "h-courses" }, "Courses")),
  );
  view.querySelector(".course-home").prepend(courses);
  showCourses(courses).catch(() => courses.remove());
  try {
    const { assignments } = await course.list();
    if (!list.isConnected) return; // the list was shown again meanwhile (a token typed): the newer one says
    accessOk(null);
    say(
      note,
      "ok",
      assignments.length
        ? `${assignments.length} assignment${assignments.length > 1 ? "s" : ""}, the newest last.`
        : "None yet: publish one with the form.",
    );
    list.replaceChildren(
      ...assignments.map((a) =>
        h(
          "li",
          { dataset: { id: a.id } },
          h("a", { href: `#${a.id}` }, a.name),
          h(
            "span",
            { class: "muted" },
            ` · ${a.course} · due ${when(a.deadline)} · ${a.students} student${a.students === 1 ? "" : "s"} · version ${a.version}`,
          ),
        ),
      ),
    );
    showAudit(assignments, list.closest(".course-home")).catch(() => {});
  } catch (err) {
    if (!list.isConnected) return;
    accessOk(err);
    say(
      note,
      "error",
      tokenProblem(err, !!tokens.instructor())
        ? "Sign in first: see above."
        : `Could not list the assignments: ${err.message}`,
    );
  }
}

/** The courses' audit trail (audit.js), below the home's panels, once the token is known to be staff's. */
async function showAudit(assignments, home) {
  const { courses } = await course.courses();
  if (!courses.length || board || !home.isConnected) return; // another view (or list) was shown meanwhile
  const panel = new AuditPanel(courses, assignments, { access: accessOk });
  home.append(panel.root);
  await panel.load();
}

/** The courses the token sees (the admin: every one, with forms for a new course and its staff; an instructor
 * or a TA: theirs), and which one the publish form publishes into. */
async function showCourses(panel) {
  const { courses } = await course.courses();
  const mine = courses.length === 1 ? await course.courseView(courses[0].id) : null;
  // the list shown again meanwhile (a token typed while the last one's courses were read): that one's courses
  // say who is signed in and which course to publish into, not this older answer
  if (!panel.isConnected) return;
  const role = mine?.you?.role;
  // a course just created is the one to publish into (it stayed on the first course)
  const into = courses.some((c) => c.id === madeCourse) ? madeCourse : course.into;
  const pick = h(
    "select",
    { id: "course-into", "aria-label": "Course to publish into" },
    ...courses.map((c) => h("option", { value: c.id, selected: c.id === into }, `${c.name} (${c.id})`)),
  );
  pick.addEventListener("change", () => (course.into = pick.value));
  course.into = courses.length > 1 ? pick.value : null;
  const items = courses.map((c) =>
    h(
      "li",
      { dataset: { id: c.id } },
      h("strong", {}, c.name),
      h(
        "span",
        { class: "muted" },
        ` · ${c.id} · ${c.assignments} assignment${c.assignments === 1 ? "" : "s"} · ${c.students} student${c.students === 1 ? "" : "s"} on its roster`,
      ),
    ),
  );
  const parts = [
    h("div", { class: "panel-head" }, h("h2", { id: "h-courses" }, "Courses")),
    h("ul", { class: "course-list", id: "course-list" }, ...items),
  ];
  if (role && role !== "admin") {
    signedAs = `Signed in as ${role === "ta" ? "a TA" : "an instructor"} of ${mine.name}.`;
    say(access, "ok", signedAs);
    showRole(role);
  }
  if (role === "ta") document.querySelector('[aria-labelledby="h-publish"]')?.remove(); // publishing is the instructors'
  if (role && role !== "admin")
    parts.push(
      h(
        "p",
        { class: "hint", id: "course-role" },
        `You are ${role === "ta" ? "a TA" : "an instructor"} of ${mine.name}${role === "ta" ? ": you follow the class, grant extensions and regrade; publishing is the instructors'." : "."}`,
      ),
    );
  if (courses.length > 1) parts.push(h("p", {}, h("label", { for: "course-into" }, "Publish into "), pick));
  if (!role || role === "admin" || role === "instructor") parts.push(staffForm(courses, role !== "instructor"));
  panel.replaceChildren(...parts);
}

/** Add an instructor or a TA to a course (and, for the admin, make a course): their link is shown once here. */
function staffForm(courses, admin) {
  const out = h("p", { class: "hint", id: "staff-status", role: "status", "aria-live": "polite" });
  const cid = h(
    "select",
    { id: "staff-course" },
    ...courses.map((c) => h("option", { value: c.id, selected: c.id === madeCourse }, c.id)),
  );
  const pid = h("input", { id: "staff-id", required: true, maxlength: 80, autocomplete: "off" });
  const name = h("input", { id: "staff-name", maxlength: 200, autocomplete: "off" });
  const role = h(
    "select",
    { id: "staff-role" },
    h("option", { value: "ta" }, "TA"),
    h("option", { value: "instructor" }, "instructor"),
  );
  const form = h(
    "form",
    { class: "staff-form", id: "staff-form" },
    h("h3", {}, "Add staff"),
    h("label", { for: "staff-course" }, "Course"),
    cid,
    h("label", { for: "staff-id" }, "Their id"),
    pid,
    h("label", { for: "staff-name" }, "Name"),
    name,
    h("label", { for: "staff-role" }, "Role"),
    role,
    h("button", { type: "submit" }, "Add"),
    out,
  );
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    try {
      const s = await course.addStaff(cid.value, { id: pid.value.trim(), name: name.value.trim(), role: role.value });
      out.replaceChildren(
        `${s.name} is ${s.role === "ta" ? "a TA" : "an instructor"} of ${cid.value}. Send them this link (it carries their token): `,
        linkBox(s.link, { id: "staff-link", label: `Copy ${s.name}'s link` }),
      );
    } catch (err) {
      out.textContent = `Not added: ${err.message}`;
    }
  });
  if (!admin) return form;
  const nid = h("input", {
    id: "new-course-id",
    required: true,
    maxlength: 40,
    autocomplete: "off",
    pattern: "[A-Za-z0-9][A-Za-z0-9_\\-]*",
  }); // the server's COURSE_ID; `-` escaped: Chromium compiles it with the v flag
  const nname = h("input", { id: "new-course-name", maxlength: 200, autocomplete: "off" });
  const ntokens = h("input", {
    id: "new-course-tokens",
    type: "number",
    min: "0",
    max: "60",
    step: "1",
    value: "0",
    title: "days each student may spend on late work, shared by the course's assignments",
  });
  const made = h("p", { class: "hint", role: "status", "aria-live": "polite" });
  const create = h(
    "form",
    { class: "staff-form", id: "course-form" },
    h("h3", {}, "New course"),
    h("label", { for: "new-course-id" }, "Id"),
    nid,
    h("label", { for: "new-course-name" }, "Name"),
    nname,
    h("label", { for: "new-course-tokens" }, "Late tokens (days per student)"),
    ntokens,
    h("button", { type: "submit" }, "Create"),
    made,
  );
  create.addEventListener("submit", async (e) => {
    e.preventDefault();
    try {
      madeCourse = nid.value.trim();
      await course.createCourse({ id: madeCourse, name: nname.value.trim(), late_tokens: Number(ntokens.value || 0) });
      showList();
    } catch (err) {
      made.textContent = `Not created: ${err.message}`;
    }
  });
  return h("div", {}, create, form);
}

async function route() {
  const { id, student } = fromHash();
  if (!id) return showList();
  if (board?.aid === id) {
    if (student && student !== board.open_) board.showStudent(student);
    return;
  }
  board?.close();
  board = new Board(id, view, { access: accessOk, onRole: showRole });
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
