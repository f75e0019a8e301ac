// The dashboard's "Grading queue" panel (web/course.html, an assignment whose spec has manual items;
// docs/assignments.md, "Staff-graded items"): the next submission to grade (GET .../grading/next), with the
// student's render beside the reference, their scene and the auto-graded results, and one fieldset per manual
// item: a checkbox per rubric level, a comment. Each change is saved at once (PUT .../manual/{item}).
// Keyboard only: 1-9 toggle the levels of the current item (the one holding the focus, else the first),
// n the next submission, b the one before, Tab moves to the comment (and on to the next item), Escape leaves
// a comment for its item's first level. An instructor assigns graders (the staff chosen in "Graders", then
// "Assign evenly": the roster dealt in turn), switches anonymous grading and releases. Once graders are assigned,
// "Queue" says whose submissions "Grade the next submission" takes: mine (the caller's own) or all.
import { request, showImage } from "../api.js";
import { h } from "../util.js";
import { AS, course, say } from "./instructor_util.js";

const pts = (x) => (x === null || x === undefined ? "–" : String(Math.round(x * 1000) / 1000));
const signed = (x) => (x >= 0 ? `+${pts(x)}` : `−${pts(-x)}`);

const grading = {
  state: (aid) => request("GET", `${course.url(aid)}/grading`, undefined, { ...AS, cache: "no-store" }),
  next: (aid, after, all) => {
    const q = new URLSearchParams();
    if (after) q.set("after", after);
    if (all) q.set("all", "true");
    return request("GET", `${course.url(aid)}/grading/next${q.size ? `?${q}` : ""}`, undefined, {
      ...AS,
      cache: "no-store",
    });
  },
  one: (aid, sid) =>
    request("GET", `${course.url(aid)}/grading/submissions/${encodeURIComponent(sid)}`, undefined, {
      ...AS,
      cache: "no-store",
    }),
  put: (aid, sid, item, body) =>
    request(
      "PUT",
      `${course.url(aid)}/submissions/${encodeURIComponent(sid)}/manual/${encodeURIComponent(item)}`,
      body,
      AS,
    ),
  release: (aid) => request("POST", `${course.url(aid)}/release`, undefined, AS),
  settings: (aid, body) => request("PUT", `${course.url(aid)}/grading/settings`, body, AS),
  assign: (aid, graders) => request("POST", `${course.url(aid)}/grading/assign`, { graders }, AS),
};

export class GradingPanel {
  constructor(aid, { access, may }) {
    this.aid = aid;
    this.access = access;
    this.may = may; // (action): what the caller's role may do (an instructor releases; a TA grades)
    this.sub = null; // the submission shown (the queue's answer)
    this.history = []; // the submissions shown before (b)
    this.current = 0; // the item 1-9 act on
    this.state = null; // GET .../grading's answer
    this.scopeTouched = false; // the queue's scope chosen by the caller (else: mine when assigned, else all)
    this.status = h("p", { id: "grading-status", class: "message", role: "status", "aria-live": "polite" });
    this.card = h("div", { id: "grading-card" });
    this.card.addEventListener("keydown", (e) => this.key(e));
    this.card.addEventListener("focusin", (e) => {
      const set = e.target.closest("fieldset[data-item]");
      if (set) this.current = Number(set.dataset.index);
    });
    this.start = h(
      "button",
      { type: "button", id: "grading-start", onclick: () => this.next() },
      "Grade the next submission",
    );
    this.scope = h(
      "select",
      {
        id: "grading-scope",
        onchange: () => {
          this.scopeTouched = true;
          if (this.state) this.showState(this.state);
        },
      },
      h("option", { value: "mine" }, "mine"),
      h("option", { value: "all" }, "all"),
    );
    this.scopeBox = h("label", { class: "inline", for: "grading-scope", hidden: true }, "Queue: ", this.scope);
    const tools = [this.start, this.scopeBox];
    this.gradersBox = null;
    if (this.may("publish")) {
      this.staffList = h("ul", { class: "grading-staff", id: "grading-staff" });
      this.assignButton = h(
        "button",
        { type: "button", id: "grading-assign", onclick: () => this.assign() },
        "Assign evenly",
      );
      this.gradersBox = h(
        "fieldset",
        { class: "grading-graders", id: "grading-graders" },
        h("legend", {}, "Graders"),
        h(
          "p",
          { class: "hint", id: "grading-graders-hint" },
          "Choose who grades, then Assign evenly: the roster's students are dealt to them in turn, as many each within one. Each grader's queue then holds their own.",
        ),
        this.staffList,
        this.assignButton,
      );
      this.anonymous = h("input", { type: "checkbox", id: "grading-anonymous", onchange: () => this.setAnonymous() });
      this.releaseButton = h(
        "button",
        { type: "button", id: "grading-release", onclick: () => this.release() },
        "Release the manual grades",
      );
      tools.push(
        h(
          "label",
          { class: "inline", for: "grading-anonymous" },
          this.anonymous,
          " Anonymous grading (names hidden until the release)",
        ),
        this.releaseButton,
      );
    }
    this.summary = h("p", { id: "grading-summary", class: "hint" });
    this.root = h(
      "section",
      { class: "panel board-grading", id: "grading", "aria-labelledby": "h-grading" },
      h(
        "div",
        { class: "panel-head" },
        h("h2", { id: "h-grading" }, "Grading queue"),
        h("span", { class: "toolbar" }, ...tools),
      ),
      h(
        "p",
        { class: "hint", id: "grading-keys" },
        "Keys: 1–9 choose the levels of the current item, Tab moves to its comment and on to the next item, n the next submission, b the one before. Each choice is saved at once.",
      ),
      this.summary,
      this.gradersBox,
      this.status,
      this.card,
    );
  }

  close() {}

  async load() {
    try {
      this.showState(await grading.state(this.aid));
    } catch (err) {
      if (!this.access(err)) say(this.status, "error", `Could not read the grading queue: ${err.message}`);
    }
  }

  showState(st) {
    this.state = st;
    if (this.anonymous) this.anonymous.checked = st.anonymous;
    const graders = st.graders || [];
    const mine = graders.some((g) => g.id === st.you);
    this.scopeBox.hidden = !graders.length;
    if (!mine && !this.scopeTouched) this.scope.value = "all";
    const all = this.scope.value === "all" || !graders.length;
    const released = st.released ? `released ${st.released_at}` : "not released: students see the auto part only";
    const dealt = graders.length ? ` Graders: ${graders.map((g) => `${g.id} ${g.students}`).join(", ")}.` : "";
    const left = all ? (st.remaining_all ?? st.remaining) : st.remaining;
    this.summary.textContent = `${left} submission(s) to grade${all ? "" : " in your queue"}; manual items worth ${pts(st.max_points)} points, ${released}.${dealt}`;
    if (this.staffList && !this.staffList.childElementCount) {
      const chosen = new Set(graders.map((g) => g.id));
      this.staffList.replaceChildren(
        ...(st.staff || []).map((s, i) => {
          const box = h("input", {
            type: "checkbox",
            id: `grading-grader-${i}`,
            checked: chosen.has(s.id),
            dataset: { person: s.id },
          });
          return h(
            "li",
            {},
            box,
            h("label", { for: box.id }, ` ${s.name || s.id} (${s.id}, ${s.role === "ta" ? "TA" : s.role})`),
          );
        }),
      );
    }
  }

  async assign() {
    const ids = [...this.staffList.querySelectorAll("input:checked")].map((b) => b.dataset.person);
    if (!ids.length) {
      say(this.status, "error", "Choose at least one grader first.");
      return;
    }
    try {
      const r = await grading.assign(this.aid, ids);
      say(this.status, "ok", `Assigned evenly: ${r.graders.map((g) => `${g.id} ${g.students}`).join(", ")}.`);
      this.load();
    } catch (err) {
      if (!this.access(err)) say(this.status, "error", `Could not assign the graders: ${err.message}`);
    }
  }

  /** Before reading another submission ("n", "b"): the saves made so far land first (a level pressed just before
   * "b" then "n" would come back without it: the card read before its PUT landed), and only the latest asked is
   * drawn (a quick "n" then "b" answered out of order would show the wrong card). The ticket's `latest()`. */
  async moving() {
    const asked = (this.moved = (this.moved || 0) + 1);
    await Promise.resolve(this.saving).catch(() => {}); // one that failed has said so
    return () => asked === this.moved;
  }

  async next() {
    const after = this.sub?.submission;
    try {
      const latest = await this.moving();
      const r = await grading.next(this.aid, after, this.scope.value === "all");
      if (!latest()) return;
      if (!r) {
        if (this.sub) this.history.push(this.sub.submission);
        this.sub = null;
        this.card.replaceChildren(h("p", { id: "grading-done" }, "Nothing left to grade."));
        say(this.status, "info", "Every submission is graded.");
        this.load();
        return;
      }
      if (this.sub && this.sub.submission !== r.submission) this.history.push(this.sub.submission);
      this.show(r);
    } catch (err) {
      if (!this.access(err)) say(this.status, "error", `Could not read the next submission: ${err.message}`);
    }
  }

  async back() {
    const sid = this.history.pop();
    if (!sid) {
      say(this.status, "info", "No submission before this one.");
      return;
    }
    try {
      const latest = await this.moving();
      const r = await grading.one(this.aid, sid);
      if (latest()) this.show(r);
    } catch (err) {
      if (!this.access(err)) say(this.status, "error", `Could not read that submission: ${err.message}`);
    }
  }

  show(r) {
    this.sub = r;
    this.current = 0;
    const render = h("img", { alt: `${r.label}'s render`, id: "grading-render" });
    const reference = h("img", { alt: "The reference", id: "grading-reference" });
    if (r.render) showImage(render, r.render, AS);
    if (r.reference) showImage(reference, r.reference, AS);
    const pictures = h(
      "div",
      { class: "grading-pictures" },
      h(
        "figure",
        { class: "grade-fig" },
        h("div", { class: "fig-box" }, render),
        h("figcaption", {}, r.render ? "Their render" : "No render"),
      ),
      h(
        "figure",
        { class: "grade-fig" },
        h("div", { class: "fig-box" }, reference),
        h("figcaption", {}, "The reference"),
      ),
    );
    const auto = r.auto || {};
    const tests = (auto.feedback?.tests || []).map((t) =>
      h(
        "li",
        {},
        `${t.name}: ${t.status ?? "–"}${t.score !== undefined && t.score !== null ? ` (${pts(t.score)} / ${pts(t.max_score)})` : ""}`,
      ),
    );
    const scene = h("pre", { class: "grading-scene", id: "grading-scene", tabindex: "0", "aria-label": "Their scene" });
    const details = h("details", { class: "grading-scene-box" }, h("summary", {}, "Their scene (JSON)"), scene);
    if (r.scene) {
      details.addEventListener("toggle", async () => {
        if (!details.open || scene.textContent) return;
        try {
          scene.textContent = await (
            await request("GET", r.scene, undefined, { ...AS, raw: true, cache: "no-store" })
          ).text();
        } catch (err) {
          scene.textContent = `Could not read the scene: ${err.message}`;
        }
      });
    }
    this.items = r.items.map((item, i) => this.itemSet(item, i, r.manual.items[i]));
    this.card.replaceChildren(
      h("h3", { id: "grading-who", tabindex: "-1" }, `${r.label}${auto.late ? " (late)" : ""}`),
      h(
        "p",
        { id: "grading-auto" },
        `Autograder: ${pts(auto.score)} / ${pts(auto.max_score)} (${auto.status}). ${r.remaining ?? 0} left in the queue.`,
      ),
      tests.length ? h("ul", { class: "grading-tests", "aria-label": "The autograder's tests" }, tests) : null,
      pictures,
      r.scene ? details : null,
      ...this.items.map((x) => x.set),
      h("p", { id: "grading-manual" }, this.totalWords()),
    );
    this.items[0]?.boxes[0]?.focus();
    say(this.status, "info", `Grading ${r.label}.`);
  }

  itemSet(item, i, grade) {
    const id = (s) => `grading-${i}-${s}`;
    const chosen = new Set(grade?.rubric || []);
    const boxes = item.rubric.map((level, j) =>
      h("input", {
        type: "checkbox",
        id: id(`level-${j}`),
        checked: chosen.has(level.name),
        dataset: { level: level.name },
        "aria-keyshortcuts": String(j + 1),
        onchange: () => this.save(i),
      }),
    );
    const comment = h("textarea", { id: id("comment"), rows: 2, "aria-label": `Comment on ${item.name}` });
    comment.value = grade?.comment || "";
    comment.addEventListener("change", () => this.save(i));
    const score = h(
      "p",
      { class: "grading-item-points", id: id("points") },
      `${pts(grade?.points)} / ${pts(item.points)}`,
    );
    const set = h(
      "fieldset",
      { class: "grading-item", dataset: { item: item.name, index: String(i) } },
      h("legend", {}, `${item.name} (${pts(item.points)} points)`),
      item.instructions ? h("p", { class: "hint" }, item.instructions) : null,
      h(
        "ul",
        { class: "grading-levels" },
        item.rubric.map((level, j) =>
          h(
            "li",
            {},
            boxes[j],
            h(
              "label",
              { for: boxes[j].id },
              h("kbd", {}, String(j + 1)),
              ` ${level.name} (${signed(level.points)})`,
              level.description ? ` – ${level.description}` : "",
            ),
          ),
        ),
      ),
      h("label", { for: comment.id, class: "grade-label" }, `Comment on ${item.name}`),
      comment,
      score,
    );
    return { item, set, boxes, comment, score };
  }

  totalWords() {
    const m = this.sub.manual;
    return `Manual part: ${pts(m.points)} / ${pts(m.max_points)}${m.complete ? " (every item graded)" : ""}.`;
  }

  key(e) {
    if (e.target.tagName === "TEXTAREA") {
      if (e.key === "Escape") this.items[this.current]?.boxes[0]?.focus();
      return;
    }
    if (e.altKey || e.ctrlKey || e.metaKey) return;
    if (/^[1-9]$/.test(e.key)) {
      const box = this.items[this.current]?.boxes[Number(e.key) - 1];
      if (!box) return;
      e.preventDefault();
      box.checked = !box.checked;
      this.save(this.current);
    } else if (e.key === "n") {
      e.preventDefault();
      this.next();
    } else if (e.key === "b") {
      e.preventDefault();
      this.back();
    }
  }

  /** Saves go one after another, in the order they were made: two at once could land out of order (a box's
   * older state over its newer one) and the status would name whichever answered last. Each sends the item as it
   * was when it was made, so moving on to the next submission loses nothing. */
  save(i) {
    const x = this.items[i];
    const sid = this.sub.submission;
    const body = { rubric: x.boxes.filter((b) => b.checked).map((b) => b.dataset.level), comment: x.comment.value };
    const send = () => this.send(i, x, sid, body);
    this.saving = (this.saving || Promise.resolve()).then(send, send); // one that threw does not stop the next
    return this.saving;
  }

  async send(i, x, sid, body) {
    try {
      const r = await grading.put(this.aid, sid, x.item.name, body);
      if (this.sub?.submission !== sid) return;
      this.sub.manual = r.manual;
      x.score.textContent = `${pts(r.manual.items[i].points)} / ${pts(x.item.points)}`;
      this.card.querySelector("#grading-manual").textContent = this.totalWords();
      const said = body.comment ? ", with a comment" : "";
      say(this.status, "ok", `Saved ${x.item.name}: ${pts(r.manual.items[i].points)} points${said}.`);
    } catch (err) {
      if (!this.access(err)) say(this.status, "error", `Could not save ${x.item.name}: ${err.message}`);
    }
  }

  async release() {
    try {
      await grading.release(this.aid);
      say(this.status, "ok", "Released: students see their manual grades, and the exports and the LMS have them.");
      this.load();
    } catch (err) {
      if (!this.access(err)) say(this.status, "error", `Could not release: ${err.message}`);
    }
  }

  async setAnonymous() {
    try {
      await grading.settings(this.aid, { anonymous: this.anonymous.checked });
      this.load();
    } catch (err) {
      if (!this.access(err)) say(this.status, "error", `Could not change anonymous grading: ${err.message}`);
    }
  }
}

export { grading };
