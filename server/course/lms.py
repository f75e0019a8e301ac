"""The course in an LMS (LTI 1.3 Advantage, docs/lti.md): what a checked launch opens, the assignment an
instructor picks for a link (Deep Linking 2.0), grades sent back (Assignment and Grade Services) and the roster
read from the LMS (Names and Role Provisioning). The launch itself is checked in server/lti/ (signature, claims,
nonce, state); this module is what a checked launch means to a course.

- **A context is a course.** An LMS course (its `context`) is linked to one course here
  (`course_lti_contexts`): by an admin (`python -m server.lti` / the API), or made at the first launch by one of
  its instructors (its id from the context's label, its name the context's title). A student's launch into a
  context that no instructor has opened yet is refused with a page that says so.
- **People.** A launch's user is `<platform id>:<sub>` (`lti_user`). An LMS instructor or administrator is an
  instructor of the course, a teaching assistant a TA, a learner a member of its roster, enrolled in every
  assignment (as a course roster is). A roster row of the same email with no LMS user yet is the same person.
  The launch answers with a redirect that carries the person's token in the fragment (never a cookie): the
  student to their assignment's page, staff to /course. The token is the derived one (people.py), the same at
  every launch, so a student's workspace jobs follow them.
- **A link is an assignment.** A resource link made by Deep Linking carries `custom.assignment`; one made
  otherwise is bound the first time an instructor launches it and picks one. `course_lti_links` keeps each
  link's assignment and its AGS line item.
- **Grades back** are rows first, posted by a thread: server/course/lms_poster.py. The tables: lms_store.py.
- **The roster from the LMS**: the NRPS memberships of a context, every page (`rel="next"`), as members and
  staff of its course, at each staff launch and on demand; the dashboard then shows who has not submitted.
"""

from __future__ import annotations

import html
import json
import logging
import re
import secrets
import threading
from collections.abc import Callable

from server.core.answers import Answer, Page, Redirect
from server.core.roles import STAFF, Kind, Role
from server.core.security import token_hash
from server.course.lms_poster import Poster
from server.course.lms_store import LmsStore
from server.course.people import COURSE_ID
from server.course.schema import MemberRow
from server.course.service import Course
from server.lti.pages import page as lti_page
from server.lti.roles import course_role
from server.lti.services import deep_link_response
from server.lti.store import PlatformRow, on_platform, platform_origins, url_origin
from tracer.grading import student_name
from tracer.tools.spreadsheet import clean_name

log = logging.getLogger(__name__)

PICK_SECONDS = 600  # a picker's form (and a claim form) is good this long
MAX_CLAIMS = 10000  # claim forms held at once (the oldest dropped past it)


def lti_user(platform: PlatformRow, sub: str) -> str:
    return f"{platform['id']}:{sub}"


def page(title: str, body: str, status: int = 200, extra_csp: str = "") -> Page:
    """A small page of the tool's own (the picker, a refusal): server/lti/pages.py's, with a policy of its own
    when it posts a form to the LMS (`extra_csp`)."""
    out = lti_page(title, body, status, ' class="lti-page"')
    if extra_csp:
        out.headers["Content-Security-Policy"] = extra_csp
    return out


def refused(title: str, message: str, status: int = 403) -> Page:
    return page(
        title, f'<h1>{html.escape(title)}</h1><p class="message" data-kind="error">{html.escape(message)}</p>', status
    )


def not_accepted(settings: dict) -> Page | None:
    """The refusal of a deep-linking request whose `accept_types` has no `ltiResourceLink` (the one kind of item
    this tool returns: a link that launches an assignment); None where it is accepted."""
    types = settings.get("accept_types")
    if isinstance(types, list) and "ltiResourceLink" in types:
        return None
    named = ", ".join(str(t)[:40] for t in types[:10]) if isinstance(types, list) and types else "none"
    return refused("The LMS does not take an assignment link here", "This place in the LMS accepts these kinds of "
                   f"content: {named}. The tool adds assignments as LTI resource links (ltiResourceLink) only: add "
                   "it where the LMS offers external tool links (an assignment or a module item).", 400)  # fmt: skip


class Lms:
    """The course's side of LTI: `launched` (the launch handler of server/lti), the picker, grades back and
    the roster from the LMS. `services`: server/lti's ServiceClient (tokens, scores, memberships)."""

    def __init__(self, course: Course, services, keys, platforms: Callable[[str], PlatformRow | None], clock=None):
        self.course, self.services, self.keys, self.platforms = course, services, keys, platforms
        self.store = LmsStore(course.settings.data_dir)
        self.now = clock or course.now
        self._lock = threading.Lock()
        self._claims: dict[str, dict] = {}  # claim forms of learners whose email is a roster student's
        self.poster = Poster(course, self.store, services, platforms, lambda: self.now())

    def start(self) -> None:
        """The poster thread (grades back): the rows a stopped server left are posted too."""
        self.poster.start()

    def stop(self) -> None:
        self.poster.stop()

    # -- the launch ----------------------------------------------------------------------------

    def launched(self, launch, base: str) -> Answer:
        """server/lti's launch handler (called in a thread: it reads and writes the course's tables)."""
        return self.launch(launch, base)

    def launch(self, launch, base: str) -> Answer:
        role = course_role(launch.roles)
        platform = launch.platform
        if role is None:
            message = ("The LMS says you are neither an instructor, a TA nor a student of this course (an observer "
                       "or a guest): the tool opens for those only.")  # fmt: skip
            return refused("Not a role of the course", message)
        context = launch.context or {}
        if not context.get("id"):
            return refused("No course in the launch", "The launch names no LMS course (context): add the tool "
                           "inside a course, not at the site's level.", 400)  # fmt: skip
        cid = self.course_of(platform, context, role)
        if cid is None:
            return refused("This course is not set up yet", "No instructor of this course has opened the tool "
                           "yet: your instructor opens it once from the LMS, then it opens for you too.")  # fmt: skip
        if launch.nrps and launch.nrps.get("context_memberships_url"):
            self.store.set_memberships(platform["id"], context["id"], launch.nrps["context_memberships_url"], None)
        if (role == Role.STUDENT and launch.email and not platform.get("trust_emails")
                and self.course.store.by_lti(cid, Kind.STUDENT, lti_user(platform, launch.sub)) is None
                and self.email_match(cid, launch.email) is not None):  # fmt: skip
            return self.claim_page(cid, platform, launch)
        person, token = self.person(cid, platform, launch, role)
        if role in STAFF and launch.nrps:
            threading.Thread(target=self.sync_quietly, args=(cid,), name="lti-roster", daemon=True).start()
        if launch.message_type == "LtiDeepLinkingRequest":
            if role != Role.INSTRUCTOR:
                return refused("Only an instructor picks", "Adding the tool to the course is an instructor's.")
            if (wrong := not_accepted(launch.deep_linking or {})) is not None:
                return wrong
            return self.picker(cid, platform, launch.deployment_id, launch.deep_linking or {}, None, token, base)
        link_id = (launch.resource_link or {}).get("id")
        aid = (launch.custom or {}).get("assignment")
        known = self.store.link(platform["id"], link_id) if link_id else None
        if not aid and known is not None:
            aid = known["assignment_id"]
        if aid and (self.course.store.assignment(aid) or {}).get("course_id") != cid:
            return refused("Not an assignment of this course", f"The link names assignment {aid[:40]!r}, which is "
                           "not one of this course's: ask your instructor to pick it again.", 404)  # fmt: skip
        lineitem = (launch.ags or {}).get("lineitem")
        if link_id and aid and not lineitem and (launch.ags or {}).get("lineitems"):
            known_item = (known or {}).get("lineitem") if known and known["assignment_id"] == aid else None
            lineitem = known_item or self.line_item(platform, launch.ags["lineitems"], link_id, aid)
        if link_id:
            self.store.keep_link(platform["id"], link_id, cid, aid, lineitem, self.now())
        if not aid:  # a course's navigation link, or an assignment link not bound yet
            if role == Role.STUDENT:  # their course's page: the assignments they are on
                return Redirect(f"/courses/{cid}#token={token}")
            if role == Role.TA:
                return Redirect(f"/course#token={token}")
            return self.picker(cid, platform, launch.deployment_id, None, link_id, token, base)
        if role in STAFF:
            return Redirect(f"/course#token={token}&open={aid}")
        self._enrol(aid, person)  # a member enrolled on every assignment is on it already
        return Redirect(f"/assignments/{aid}#token={token}")

    def line_item(self, platform: PlatformRow, lineitems: str, link_id: str, aid: str) -> str | None:
        """The gradebook column of a link whose launch names none (a link made without deep linking): the
        platform's column of that link, else a new one of the assignment's points; None if the platform says
        no (its grades then stay here, in grades.csv and the gradebook export)."""
        try:
            items = self.services.line_items(platform, lineitems, link_id)
            if items:
                return items[0]["id"]
            a = self.course.assignment(aid)
            points = self.course.spec(aid, a["version"]).max_score()
            item = self.services.create_line_item(platform, lineitems, a["spec"]["name"], points, link_id, None, aid)
            return item["id"]
        except Exception as e:  # noqa: BLE001 (the launch opens all the same; the column is asked for next time)
            log.warning("no gradebook column for link %s of platform %s: %s", link_id, platform["id"], e)
            return None

    def _enrol(self, aid: str, student: str) -> None:
        self.course.store.enrol(aid, student, self.now(), self.course.by("lms", "LMS launch"))

    def course_of(self, platform: PlatformRow, context: dict, role: str) -> str | None:
        """The course linked to the LMS course; made at an instructor's first launch."""
        known = self.store.context(platform["id"], context["id"])
        if known is not None:
            return known["course_id"]
        if role != Role.INSTRUCTOR:
            return None
        title = " ".join(str(context.get("title") or context.get("label") or "LMS course").split())[:200]
        stem = re.sub(r"[^A-Za-z0-9_-]+", "-", str(context.get("label") or title)).strip("-_")[:30] or "lms"
        cid = stem if COURSE_ID.fullmatch(stem) and self.course.store.course(stem) is None else None
        while cid is None or not self.course.store.add_course(cid, title, self.now()):
            cid = f"{stem[:30]}-{secrets.token_hex(3)}"
        self.store.link_context(platform["id"], context["id"], cid, title, self.now())
        log.info("course %s made for LMS course %r of platform %s", cid, title, platform["id"])
        return cid

    def person(self, cid: str, platform: PlatformRow, launch, role: str, why: str = "LMS launch") -> tuple[str, str]:
        """The launch's user as staff or a member of the course (made or updated): (their id, their token); the
        change audited as the LMS's (`why`: a launch, or the roster's sync)."""
        who = lti_user(platform, launch.sub)
        name = launch.name or " ".join(x for x in (launch.given_name, launch.family_name) if x) or launch.email or ""
        name = " ".join(clean_name(name)[0].split())[:200]  # no control or bidi override into pages and exports
        email = launch.email or ""
        kind = Kind.STAFF if role in STAFF else Kind.STUDENT
        known = self.course.store.by_lti(cid, kind, who)
        if known is None and kind == Kind.STUDENT and email and platform.get("trust_emails"):
            known = self.email_match(cid, email)  # only where the platform's emails identify people
        pid = (known or {}).get("person") or (known or {}).get("student") or self.new_id(cid, kind, launch, email)
        if kind == Kind.STAFF:
            row = {"person": pid, "name": name or pid, "email": email, "role": role, "lti_user": who}
            self.course.store.add_staff(cid, row, self.now(), self.course.by("lms", why))
            staff = self.course.store.staff_member(cid, pid)
            assert staff is not None  # added just above
            gen = staff["gen"]
        else:
            row = {"student": pid, "name": name or pid, "email": email, "every": 1, "lti_user": who}
            self.course.store.add_members(cid, [row], self.now(), [], self.course.by("lms", why))
            member = self.course.store.member(cid, pid)
            assert member is not None  # added just above
            if member["left_at"] is not None:  # the LMS launched them: they are in its course again
                self.course.store.set_left(cid, [pid], None, self.course.by("lms", why))
            gen = member["gen"]
        return pid, self.course.token_of(cid, kind, pid, gen)

    def email_match(self, cid: str, email: str) -> MemberRow | None:
        """The course's roster student of `email` whom no LMS user is linked to yet."""
        return next((m for m in self.course.store.members(cid) if m["email"].lower() == email.lower()
                     and not m["lti_user"]), None)  # fmt: skip

    def claim_page(self, cid: str, platform: PlatformRow, launch) -> Page:
        """A learner's first launch whose email is a roster student's, from a platform whose emails do not
        identify people (no --trust-emails): their roster link, given once while launched, links the two."""
        claim = secrets.token_urlsafe(24)
        with self._lock:
            now = self.now()
            for k in [k for k, v in self._claims.items() if v["expires"] < now]:
                del self._claims[k]
            if len(self._claims) >= MAX_CLAIMS:
                self._claims.pop(next(iter(self._claims)))
            self._claims[claim] = {"course": cid, "lti_user": lti_user(platform, launch.sub),
                                   "expires": now + PICK_SECONDS}  # fmt: skip
        body = (
            "<h1>Link your course account</h1>"
            "<p>This course has a place on its roster for your email. To be sure it is yours, paste the link your "
            "instructor sent you (it opens your assignments); this is asked once. No link? Ask your instructor.</p>"
            f'<form method="post" action="/lti/claim"><input type="hidden" name="claim" value="{claim}">'
            '<label for="lti-claim-link">Your link</label> '
            '<input id="lti-claim-link" name="link" type="url" required autocomplete="off" size="60"> '
            '<button type="submit">Link</button></form>'
        )
        return page("Link your course account", body)

    def claimed(self, claim: str, link: str) -> Page:
        """The claim form: the roster link's token, if it is a good one of an unlinked student of the claim's
        course, links the LMS user to that student (then the launch opens them)."""
        with self._lock:
            held = self._claims.pop(claim, None)
        if held is None or held["expires"] < self.now():
            return refused("This page has expired", "Open the tool from the LMS again.", 400)
        cid, who = held["course"], held["lti_user"]
        token = link.split("#token=", 1)[-1].split("&", 1)[0].strip()
        row = self.course.store.token(token_hash(token)) if token else None
        member = self.course.store.member(cid, row["person"]) if row and row["course_id"] == cid else None
        good = (member is not None and row is not None and row["kind"] == Kind.STUDENT
                and self.course.token_of(cid, Kind.STUDENT, member["student"], member["gen"]) == token)  # fmt: skip
        if (not good or member is None or member["lti_user"]
                or self.course.store.by_lti(cid, Kind.STUDENT, who) is not None):  # fmt: skip
            return refused("Not a link of this course", "That link is not a current roster link of this course "
                           "for a student who is not linked yet: ask your instructor.", 403)  # fmt: skip
        row = {"student": member["student"], "name": member["name"], "email": member["email"],
               "every": member["every"], "lti_user": who}  # fmt: skip
        self.course.store.add_members(cid, [row], self.now(), [], self.course.by("lms", "linked by their roster link"))
        log.info("LMS user %s linked to roster student %s of course %s by their link", who, member["student"], cid)
        return page("Linked", f"<h1>Linked: {html.escape(member['name'])}</h1><p>Open the tool from the LMS again: "
                    "it opens your assignments from now on.</p>")  # fmt: skip

    def new_id(self, cid: str, kind: str, launch, email: str) -> str:
        """A readable id for someone new: the LMS's SIS id, else their email's name, else their sub; made unique."""
        lis = (getattr(launch, "claims", {}) or {}).get("https://purl.imsglobal.org/spec/lti/claim/lis") or {}
        stem = "lti"
        for candidate in (lis.get("person_sourcedid"), email.split("@")[0] if email else None, f"lti-{launch.sub}"):
            if candidate and student_name(str(candidate))[:60].strip("._"):
                stem = student_name(str(candidate))[:60].strip("._")
                break
        taken = self.course.store.member if kind == Kind.STUDENT else self.course.store.staff_member
        pid = stem
        while taken(cid, pid) is not None:
            pid = f"{stem[:60]}-{secrets.token_hex(2)}"
        return pid

    # -- the picker (Deep Linking 2.0, or binding a link) ---------------------------------------

    def picker(self, cid, platform, deployment_id, settings, link_id, token, base) -> Page:
        pid = self.store.new_pick({"platform_id": platform["id"], "deployment_id": deployment_id or "",
                                   "course_id": cid, "settings": json.dumps(settings) if settings else "",
                                   "resource_link_id": link_id, "expires": self.now() + PICK_SECONDS})  # fmt: skip
        items = []
        for aid in self.course.store.assignments(cid):
            a = self.course.store.assignment(aid)
            if a is None:  # (none: the course's ids are its assignments')
                continue
            items.append(
                f'<li><button type="submit" name="assignment" value="{aid}">{html.escape(a["spec"]["name"])}</button>'
                f' <span class="muted">due {html.escape(a["policy"]["deadline"])}</span></li>'
            )
        course_page = f"/course#token={token}"
        if not items:
            body = (
                "<h1>No assignment to add yet</h1><p>Publish one in this course first, then add the tool again: "
                f'<a href="{course_page}" target="_blank" rel="noopener">open the course page</a>.</p>'
            )
            return page("Pick an assignment", body)
        what = "to add to the LMS course" if settings else "for this link"
        body = (
            f"<h1>Pick an assignment {what}</h1>"
            f'<form method="post" action="/lti/pick"><input type="hidden" name="pick" value="{pid}">'
            f'<ul class="course-list">{"".join(items)}</ul></form>'
            f'<p class="hint">Or <a href="{course_page}" target="_blank" rel="noopener">open the course page</a> to '
            "publish another.</p>"
        )
        return page("Pick an assignment", body)

    def picked(self, pid: str, aid: str, base: str) -> Answer:
        """The picker's choice: a deep link's answer to the LMS (a signed LtiDeepLinkingResponse, posted back by
        the browser), or a link bound to the assignment (then opened)."""
        pick = self.store.take_pick(pid, self.now())
        if pick is None:
            return refused("This choice has expired", "Pick again: open the tool from the LMS once more.", 400)
        a = self.course.store.assignment(aid) if len(aid) == 32 else None
        if a is None or a["course_id"] != pick["course_id"]:
            return refused("Not an assignment of this course", "Pick one of the list.", 404)
        platform = self.platforms(pick["platform_id"])
        if platform is None:
            return refused("The LMS is no longer registered", "Ask the server's admin.", 400)
        if not pick["settings"]:
            self.store.keep_link(pick["platform_id"], pick["resource_link_id"], pick["course_id"], aid, None,
                                 self.now())  # fmt: skip
            return page("Assignment picked", f"<h1>Picked: {html.escape(a['spec']['name'])}</h1><p>Launch the "
                        "link again from the LMS to open it.</p>")  # fmt: skip
        settings = json.loads(pick["settings"])
        url = settings.get("deep_link_return_url")
        if not on_platform(platform, url):  # (checked at the launch too: a platform registered again since)
            where = ", ".join(platform_origins(platform))
            return refused("The LMS's return address is not its own", "The deep-linking return URL is not at the "
                           f"platform's registered addresses ({where}).", 400)  # fmt: skip
        if (wrong := not_accepted(settings)) is not None:
            return wrong
        item = {
            "type": "ltiResourceLink",
            "title": a["spec"]["name"],
            "url": f"{base.rstrip('/')}/lti/launch",
            "custom": {"assignment": aid},
        }
        if settings.get("accept_lineitem") is not False:  # absent: the platform did not say; false: it ignores one
            points = self.course.spec(aid, a["version"]).max_score()
            item["lineItem"] = {"scoreMaximum": points, "label": a["spec"]["name"], "resourceId": aid}
        jwt = deep_link_response(self.keys, platform, pick["deployment_id"], settings, [item], self.now())
        origins = " ".join(platform_origins(platform))  # the LMS's own pages frame this one, no one else
        csp = (f"default-src 'self'; script-src 'self'; form-action {url_origin(url)}; frame-ancestors {origins}; "
               "base-uri 'none'; object-src 'none'")  # fmt: skip
        body = (
            f"<h1>Adding {html.escape(a['spec']['name'])}</h1>"
            f'<form id="lti-return" method="post" action="{html.escape(url)}">'
            f'<input type="hidden" name="JWT" value="{html.escape(jwt)}">'
            '<button type="submit">Return to the LMS</button></form>'
            '<script src="/js/lti_return.js"></script>'
        )
        return page("Return to the LMS", body, extra_csp=csp)

    # -- the roster from the LMS (NRPS) --------------------------------------------------------

    def sync_quietly(self, cid: str) -> None:
        try:
            self.sync(cid)
        except Exception as e:  # noqa: BLE001 (a launch does not wait for it; the dashboard shows the last sync)
            log.warning("roster of course %s not read from the LMS: %s", cid, e)

    def sync(self, cid: str) -> dict:
        """Read the roster of each LMS course linked to `cid` (every page) into its members and staff. A member
        whose email is an unlinked roster student's is left for their own launch to link (`unlinked`), unless the
        platform is trusted with emails. Instructors and TAs become the course's staff (`staff`); a linked student
        no longer in any of its LMS courses (gone, or not Active) is marked inactive (`left`: kept, with their
        submissions and grades; they can no longer submit); one who is back is active again (`back`)."""
        added, seen, unlinked, staff = 0, 0, 0, 0
        active: dict[str, set[str]] = {}  # platform id -> the subs of its active students, over its contexts
        known = {m["student"] for m in self.course.store.members(cid)}  # a launch during the read is not judged by it
        for ctx in self.store.contexts(cid):
            platform = self.platforms(ctx["platform_id"])
            if platform is None or not ctx["memberships_url"]:
                continue
            subs = active.setdefault(platform["id"], set())
            for m in self.services.members(platform, ctx["memberships_url"]):
                if (m.get("status") or "Active") != "Active":
                    continue
                role = course_role(m.get("roles") or [])
                if role is not None and role in STAFF:
                    self.person(cid, platform, _Member(m), role)  # made, or their name and role brought up to date
                    staff += 1
                if role != Role.STUDENT:
                    continue
                seen += 1
                subs.add(str(m["user_id"]))
                who = f"{platform['id']}:{m['user_id']}"
                if self.course.store.by_lti(cid, Kind.STUDENT, who) is not None:
                    continue
                email = m.get("email") or ""
                if email and not platform.get("trust_emails") and self.email_match(cid, email) is not None:
                    unlinked += 1  # a roster student's email: linked by their own launch and roster link, not here
                    continue
                self.person(cid, platform, _Member(m), Role.STUDENT, "LMS roster sync")
                added += 1
            self.store.set_memberships(ctx["platform_id"], ctx["context_id"], None, self.now())
        left, back = self._leavers(cid, active, known)
        return {"course": cid, "members": seen, "added": added, "unlinked": unlinked, "staff": staff,
                "left": left, "back": back}  # fmt: skip

    def _leavers(self, cid: str, active: dict[str, set[str]], known: set[str]) -> tuple[int, int]:
        """The course's LMS students of the platforms read (`active`: their active students' subs) marked inactive
        when gone, active when back (the one place a sync changes that: an audit call goes here). A platform that
        listed no student at all is left alone (an LMS's empty answer does not empty a course), and so is a student
        who was not a member when the read began (`known`): their launch may be newer than the roster read."""
        gone, returned = [], []
        for m in self.course.store.members(cid):
            platform_id, _, sub = (m["lti_user"] or "").partition(":")
            if not active.get(platform_id) or m["student"] not in known:
                continue
            if sub not in active[platform_id] and m["left_at"] is None:
                gone.append(m["student"])
            elif sub in active[platform_id] and m["left_at"] is not None:
                returned.append(m["student"])
        by = self.course.by("lms", "LMS roster sync")
        left = self.course.store.set_left(cid, gone, self.now(), by) if gone else 0
        back = self.course.store.set_left(cid, returned, None, by) if returned else 0
        if left or back:
            log.info("roster of course %s from the LMS: %d left (inactive), %d back", cid, left, back)
        return left, back

    def board(self, aid: str, cid: str) -> dict | None:
        """What the dashboard shows of the LMS: None for a course that is in none."""
        contexts = self.store.contexts(cid)
        if not contexts:
            return None
        synced = [c["synced_at"] for c in contexts if c["synced_at"]]
        names = [c["title"] or c["context_id"] for c in contexts]  # one the admin linked has no title until a launch
        return {"contexts": names, "linked": bool(self.store.links(aid)),
                "roster_synced_at": max(synced) if synced else None, "grades": self.store.scores(aid)}  # fmt: skip


class _Member:
    """An NRPS member as `person` reads a launch."""

    def __init__(self, m: dict):
        self.sub = m["user_id"]
        self.name = m.get("name") or ""
        self.given_name, self.family_name = m.get("given_name"), m.get("family_name")
        self.email = m.get("email") or ""
        self.claims = {
            "https://purl.imsglobal.org/spec/lti/claim/lis": {"person_sourcedid": m.get("lis_person_sourcedid")}
        }
