// The form that publishes an assignment (POST /api/assignments) or a new version of one (PUT, with
// ?regrade=true to grade every submission again): the spec file (docs/grading.md) and, when the spec names
// its reference scene as a file, that file beside it; the policy (deadline, late cut-off and penalty,
// attempts, which submission counts, the starter scene, the reference shown, open) and the feedback policy
// of each test named in the spec. It is sent as multipart, as docs/assignments.md shows; a deadline typed
// in the browser's zone is sent with that zone's offset. The server's 422 errors are shown at their fields.
// "Preview what a student sees" (POST /api/assignments/preview-feedback, the same body) shows an example
// submission's feedback until the deadline and after it, as the server's own policy rule gives it: each test
// shown or hidden, the pictures, and what is held back until when; it follows the form's changes once shown.
import { debounce, h } from "../util.js";
import { localTime, pts } from "./brief.js";
import { testItem, withheldNotice } from "./feedback.js";
import { course, errorList, localValue, say, showFieldErrors, zoned, zoneName } from "./instructor_util.js";

const WHEN = [
  ["now", "now"],
  ["after_deadline", "after the deadline"],
  ["never", "never (the instructor only)"],
];
const IMAGE_TESTS = ["flip", "ssim", "psnr", "pixels"];

/** The tests a feedback policy may name, from a spec: validity, each requirement, the image tests given. */
export function specTests(spec) {
  const out = [{ key: "validity", label: "validity (the scene validates)" }];
  for (const r of Array.isArray(spec?.requirements) ? spec.requirements : []) {
    if (r && typeof r.name === "string") out.push({ key: r.name, label: `requirement: ${r.name}` });
  }
  const ref = spec?.reference && typeof spec.reference === "object" ? spec.reference : {};
  for (const k of IMAGE_TESTS) if (ref[k]) out.push({ key: k, label: `image test: ${k}` });
  return out;
}

export class AssignmentForm {
  /** `edit`: the instructor's brief of the assignment to edit (its spec and policy prefill the form). */
  constructor({ edit = null, onDone }) {
    this.edit = edit;
    this.onDone = onDone;
    this.spec = edit ? edit.spec : null; // the spec parsed from the picked file (or the current one)
    this.id = edit ? "edit" : "publish"; // one form of each on a page: the ids of its fields start with it
    this.el = this.build();
    if (edit) this.prefill(edit.policy);
  }

  field(name, label, input, help) {
    const list = errorList(`${this.id}-${name}-err`, `Problems with ${label}`);
    input.id ||= `${this.id}-${name}`;
    input.setAttribute("aria-describedby", [help ? `${input.id}-help` : null, list.id].filter(Boolean).join(" "));
    this.fields[name] = { input, list };
    return h(
      "div",
      { class: "af-field", dataset: { field: name } },
      h("label", { for: input.id }, label),
      input,
      help ? h("p", { class: "hint", id: `${input.id}-help` }, help) : null,
      list,
    );
  }

  build() {
    const id = this.id;
    this.fields = {};
    this.specInput = h("input", { type: "file", accept: ".json,application/json", name: "spec", required: !this.edit });
    this.specInput.addEventListener("change", () => (this.specRead = this.readSpec()));
    this.refInput = h("input", { type: "file", accept: ".json,application/json", name: "reference" });
    this.refBox = this.field(
      "reference",
      "Reference scene file",
      this.refInput,
      "The spec names its reference scene as a file: pick that file (it is sent beside the spec).",
    );
    this.refBox.hidden = true;
    this.deadline = h("input", { type: "datetime-local", name: "deadline", required: true });
    this.lateUntil = h("input", { type: "datetime-local", name: "late_until" });
    this.regradeUntil = h("input", { type: "datetime-local", name: "regrade_deadline" });
    this.penalty = h("input", {
      type: "number",
      name: "late_penalty",
      min: 0,
      max: 1,
      step: 0.05,
      value: "",
      placeholder: "0",
      inputmode: "decimal",
    });
    this.maxSubs = h("input", {
      type: "number",
      name: "max_submissions",
      min: 1,
      step: 1,
      placeholder: "no limit",
      inputmode: "numeric",
    });
    this.counts = h(
      "select",
      { name: "counts" },
      h("option", { value: "last" }, "the last graded one"),
      h("option", { value: "best" }, "the best graded one"),
    );
    this.starter = h("input", { type: "file", accept: ".json,application/json", name: "starter" });
    this.showRef = h("input", { type: "checkbox", name: "show_reference", id: `${id}-show_reference` });
    this.open = h("input", { type: "checkbox", name: "open", id: `${id}-open` });
    this.fbDefault = this.whenSelect("default", "now");
    this.fbScore = this.whenSelect("score", "", "the latest of the tests' (default)");
    this.fbRows = h("tbody", {});
    const fbList = errorList(`${id}-feedback-err`, "Problems with the feedback policy");
    this.fields.feedback = { input: this.fbDefault, list: fbList };
    this.general = errorList(`${id}-errors`, "Problems with the assignment");
    this.status = h("p", { class: "af-status", role: "status", "aria-live": "polite" });
    this.regrade = this.edit ? h("input", { type: "checkbox", id: `${id}-regrade`, checked: true }) : null;
    this.button = h("button", { type: "submit", class: "primary" }, this.edit ? "Publish the new version" : "Publish");
    this.previewButton = h("button", { type: "button", class: "af-preview-button" }, "Preview what a student sees");
    this.previewButton.addEventListener("click", () => this.preview());
    this.previewStatus = h("p", { class: "af-preview-status", role: "status", "aria-live": "polite" });
    this.previewBox = h("div", { class: "af-preview", id: `${id}-preview`, hidden: true });
    const zone = `in this browser's zone (${zoneName()}); sent with its offset`;
    const form = h(
      "form",
      {
        class: "af",
        id,
        novalidate: true,
        "aria-label": this.edit ? "A new version of the assignment" : "Publish an assignment",
      },
      h(
        "fieldset",
        {},
        h("legend", {}, "The spec"),
        this.field(
          "spec",
          this.edit ? "Edited spec file (JSON; empty: keep the current spec)" : "Spec file (JSON)",
          this.specInput,
          h(
            "span",
            {},
            "The grading spec of ",
            h("a", { href: "/reference/grading.md", target: "_blank", rel: "noopener" }, "docs/grading.md"),
            " (scenes/grading/assignment.json is the example).",
          ),
        ),
        this.refBox,
        (this.specNote = h("p", { class: "hint af-spec-note", "aria-live": "polite" })),
      ),
      h(
        "fieldset",
        { class: "af-grid" },
        h("legend", {}, "Deadline and attempts"),
        this.field("deadline", "Deadline", this.deadline, zone),
        this.field(
          "late_until",
          "Late submissions until (optional)",
          this.lateUntil,
          "Taken and marked late until then.",
        ),
        this.field(
          "late_penalty",
          "Late penalty (0 to 1)",
          this.penalty,
          "The fraction of a late submission's points taken off: 0.2 keeps 80 %.",
        ),
        this.field(
          "regrade_deadline",
          "Regrade requests until (optional)",
          this.regradeUntil,
          "Empty: a week after each student's late cut-off (their deadline without one).",
        ),
        this.field(
          "max_submissions",
          "Attempts per student",
          this.maxSubs,
          "Empty: no limit. An invalid or ungradable submission costs none.",
        ),
        this.field("counts", "The grade is", this.counts),
      ),
      h(
        "fieldset",
        { class: "af-grid" },
        h("legend", {}, "What students get"),
        this.field(
          "starter",
          "Starter scene (optional)",
          this.starter,
          this.edit?.policy?.starter ? "Empty: keep the current starter scene." : "A scene the students start from.",
        ),
        h(
          "div",
          { class: "af-field af-check" },
          this.showRef,
          h("label", { for: this.showRef.id }, "Students see the reference image"),
        ),
        h(
          "div",
          { class: "af-field af-check" },
          this.open,
          h("label", { for: this.open.id }, "Open: anyone with the link joins by a name (marked self-declared)"),
        ),
      ),
      h(
        "fieldset",
        { class: "af-feedback" },
        h("legend", {}, "Feedback: when each test is shown to the student"),
        h(
          "table",
          { class: "af-fb-table" },
          h("thead", {}, h("tr", {}, h("th", { scope: "col" }, "test"), h("th", { scope: "col" }, "shown"))),
          h(
            "tbody",
            {},
            h(
              "tr",
              {},
              h("th", { scope: "row" }, h("label", { for: this.fbDefault.id }, "every test not named below")),
              h("td", {}, this.fbDefault),
            ),
            h(
              "tr",
              {},
              h("th", { scope: "row" }, h("label", { for: this.fbScore.id }, "the score")),
              h("td", {}, this.fbScore),
            ),
          ),
          this.fbRows,
        ),
        h(
          "p",
          { class: "hint" },
          "The tests are read from the spec. After the deadline: once the student can no longer submit (their late cut-off, else their deadline). A hidden image test hides the error map, the rejected pixels and the metrics too (they would tell its result).",
        ),
        fbList,
        h("div", { class: "af-preview-go" }, this.previewButton, this.previewStatus),
        this.previewBox,
      ),
      this.edit
        ? h(
            "div",
            { class: "af-field af-check" },
            this.regrade,
            h("label", { for: this.regrade.id }, "Regrade every submission under the new version"),
          )
        : null,
      this.general,
      h("div", { class: "af-go" }, this.button, this.status),
    );
    // once a preview is shown, it follows the policy's fields
    const again = debounce(() => !this.previewBox.hidden && this.preview(), 400);
    form.addEventListener("change", () => again());
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      this.send();
    });
    this.form = form;
    this.renderTests();
    return form;
  }

  whenSelect(name, value, first = null) {
    const sel = h("select", {
      id: `${this.id}-fb-${name.replace(/[^A-Za-z0-9_-]/g, "_")}-${Math.random().toString(36).slice(2, 6)}`,
      dataset: { test: name },
    });
    if (first) sel.append(h("option", { value: "" }, first));
    for (const [v, text] of WHEN) sel.append(h("option", { value: v }, text));
    sel.value = value;
    return sel;
  }

  /** The spec file picked, read (it names the reference file the form then asks for, and the tests the feedback
   * table lists): Preview and Publish wait for it (`specRead`), and a file picked while the last one is still
   * being read wins over it. */
  async readSpec() {
    const asked = (this.specAsked = (this.specAsked || 0) + 1);
    const f = this.specInput.files?.[0];
    this.fields.spec.list.replaceChildren();
    this.specInput.removeAttribute("aria-invalid");
    if (!f) {
      this.spec = this.edit ? this.edit.spec : null;
      this.afterSpec();
      return;
    }
    const read = f.text();
    await read.catch(() => {});
    if (asked !== this.specAsked) return;
    try {
      this.spec = JSON.parse(await read);
    } catch (err) {
      this.spec = null;
      this.fields.spec.list.append(
        h("li", {}, h("span", { class: "where" }, f.name), h("span", { class: "msg" }, `not JSON: ${err.message}`)),
      );
      this.specInput.setAttribute("aria-invalid", "true");
    }
    this.afterSpec();
  }

  afterSpec() {
    const ref = this.spec?.reference;
    const named = ref && typeof ref === "object" && typeof ref.scene === "string";
    this.refBox.hidden = !named;
    this.refInput.required = !!named;
    if (named) this.refBox.querySelector("label").textContent = `Reference scene file (the spec names '${ref.scene}')`;
    this.specNote.textContent =
      this.spec && typeof this.spec === "object"
        ? `“${this.spec.name || "(no name)"}”: ${specTests(this.spec).length} tests.`
        : "";
    this.renderTests();
  }

  renderTests() {
    const kept = new Map([...this.fbRows.querySelectorAll("select")].map((s) => [s.dataset.test, s.value]));
    const given = this.edit?.policy?.feedback?.tests || {};
    const tests = specTests(this.spec);
    this.fbRows.replaceChildren(
      ...tests.map((t) => {
        const sel = this.whenSelect(t.key, "", "as every test");
        sel.value = kept.get(t.key) ?? given[t.key] ?? "";
        return h(
          "tr",
          { dataset: { test: t.key } },
          h("th", { scope: "row" }, h("label", { for: sel.id }, t.label)),
          h("td", {}, sel),
        );
      }),
    );
    if (!tests.length || !this.spec)
      this.fbRows.replaceChildren(
        h("tr", {}, h("td", { colspan: 2, class: "muted" }, "Pick the spec file to set each test's feedback.")),
      );
  }

  prefill(p) {
    this.deadline.value = localValue(p.deadline);
    this.lateUntil.value = localValue(p.late_until);
    this.regradeUntil.value = localValue(p.regrade_deadline);
    this.penalty.value = p.late_penalty ? String(p.late_penalty) : "";
    this.maxSubs.value = p.max_submissions ?? "";
    this.counts.value = p.counts || "last";
    this.showRef.checked = !!p.show_reference;
    this.open.checked = !!p.open;
    this.fbDefault.value = p.feedback?.default || "now";
    this.fbScore.value = p.feedback?.score || "";
    this.afterSpec();
  }

  /** The request's multipart body, as docs/assignments.md's curl example sends it. */
  async body() {
    const fd = new FormData();
    const spec = this.specInput.files?.[0];
    if (spec) fd.append("spec", spec, spec.name);
    else if (this.edit) fd.append("spec", JSON.stringify(this.edit.spec));
    const ref = this.refInput.files?.[0];
    if (ref && !this.refBox.hidden) fd.append("reference", ref, ref.name);
    const deadline = zoned(this.deadline.value);
    if (deadline) fd.append("deadline", deadline);
    const late = zoned(this.lateUntil.value);
    if (late) fd.append("late_until", late);
    const regrade = zoned(this.regradeUntil.value);
    if (regrade) fd.append("regrade_deadline", regrade);
    if (this.penalty.value.trim()) fd.append("late_penalty", this.penalty.value.trim());
    if (String(this.maxSubs.value).trim()) fd.append("max_submissions", String(this.maxSubs.value).trim());
    fd.append("counts", this.counts.value);
    const starter = this.starter.files?.[0];
    if (starter) fd.append("starter", starter, starter.name);
    else if (this.edit?.policy?.starter) fd.append("starter", JSON.stringify(this.edit.policy.starter));
    fd.append("show_reference", this.showRef.checked ? "true" : "false");
    fd.append("open", this.open.checked ? "true" : "false");
    const tests = {};
    for (const sel of this.fbRows.querySelectorAll("select")) if (sel.value) tests[sel.dataset.test] = sel.value;
    const feedback = { default: this.fbDefault.value, tests };
    if (this.fbScore.value) feedback.score = this.fbScore.value;
    fd.append("feedback", JSON.stringify(feedback));
    return fd;
  }

  /** The feedback of an example submission until the deadline and after it under the form's policy, as the
   * server applies it to every submission (nothing is published). */
  async preview() {
    await this.specRead; // a spec just picked, read first (else the form is checked against the last one)
    if (!this.precheck()) {
      say(this.previewStatus, "error", "Fix the fields marked above to preview.");
      return;
    }
    showFieldErrors([], this.fields, this.general);
    say(this.previewStatus, "busy", "Asking the server what a student would see…");
    const seq = (this.previewSeq = (this.previewSeq || 0) + 1);
    try {
      const p = await course.preview(await this.body());
      if (seq !== this.previewSeq) return; // a later one was asked
      this.showPreview(p);
      say(this.previewStatus, "ok", "The preview below follows the policy's fields as you change them.");
    } catch (err) {
      if (seq !== this.previewSeq) return;
      const errors = err.errors || [{ path: "", message: String(err.message || err) }];
      showFieldErrors(errors, this.fields, this.general)?.focus();
      say(
        this.previewStatus,
        "error",
        `No preview: the server refused the form (${errors.length} problem${errors.length > 1 ? "s" : ""}): see the fields marked.`,
      );
    }
  }

  showPreview(p) {
    const cols = p.moments.map((m) => {
      const fb = m.feedback;
      const head = `${this.id}-preview-${m.moment}`;
      const title =
        m.moment === "now"
          ? ["Now: until the deadline (", h("time", { datetime: p.cut_off }, localTime(p.cut_off)), ")"]
          : ["After the deadline"];
      const pictures = [
        "their render",
        ...(fb.pictures.includes("error_map.png") ? ["the error map", "the rejected pixels"] : []),
        ...(this.showRef.checked ? ["the reference"] : []),
      ];
      return h(
        "section",
        { class: "af-preview-col", dataset: { moment: m.moment }, "aria-labelledby": head },
        h("h4", { id: head }, ...title),
        h(
          "p",
          { class: "af-preview-score" },
          m.score_shown ? `Score: ${pts(m.score)} / ${pts(m.max_score)}` : `Score: hidden (out of ${pts(m.max_score)})`,
        ),
        h(
          "p",
          { class: "af-preview-pictures" },
          `Pictures: ${pictures.join(", ")}${fb.metrics ? "; the metrics against the noise baseline" : ""}.`,
        ),
        withheldNotice(fb.withheld, { who: "their" }),
        h("ol", { class: "grade-tests a-tests" }, fb.tests.map(testItem)),
      );
    });
    this.previewBox.replaceChildren(
      h("p", { class: "hint" }, `An example submission: ${p.example}.`),
      h("div", { class: "af-preview-cols" }, cols),
    );
    this.previewBox.hidden = false;
  }

  /** Problems the page can tell before asking (a field left empty), at their fields; true when none. */
  precheck() {
    const errors = [];
    if (!this.edit && !this.specInput.files?.length)
      errors.push({ path: "spec", message: "pick the spec file (JSON)" });
    if (this.specInput.getAttribute("aria-invalid") === "true" && this.fields.spec.list.children.length) return false;
    if (!this.refBox.hidden && !this.refInput.files?.length)
      errors.push({ path: "reference", message: `pick the reference scene file ('${this.spec.reference.scene}')` });
    if (!this.deadline.value) errors.push({ path: "deadline", message: "a deadline is required (a date and a time)" });
    if (errors.length) {
      showFieldErrors(errors, this.fields, this.general)?.focus();
      return false;
    }
    return true;
  }

  async send() {
    // a spec just picked, read first: before, the form was checked (and sent) as for the last one, without the
    // reference file this one names
    await this.specRead;
    if (!this.precheck()) {
      say(this.status, "error", "Fix the fields marked above.");
      return;
    }
    showFieldErrors([], this.fields, this.general);
    this.button.disabled = true;
    say(this.status, "busy", this.edit ? "Publishing the new version…" : "Publishing…");
    try {
      const body = await this.body();
      const a = this.edit ? await course.edit(this.edit.id, body, this.regrade.checked) : await course.publish(body);
      say(this.status, "ok", this.edit ? `Version ${a.version} published.` : `Published “${a.name}”.`);
      this.onDone?.(a);
    } catch (err) {
      const errors = err.errors || [{ path: "", message: String(err.message || err) }];
      const first = showFieldErrors(errors, this.fields, this.general);
      say(
        this.status,
        "error",
        `The server refused it (${errors.length} problem${errors.length > 1 ? "s" : ""}): see the fields marked.`,
      );
      first?.focus();
    } finally {
      this.button.disabled = false;
    }
  }
}
