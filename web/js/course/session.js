// Who the student is on an assignment's page, and the routes of docs/assignments.md with their token.
//
// The mailed link is /assignments/{id}#token=K. The fragment never reaches a server (nor a Referer); the page
// keeps K in localStorage under this assignment's id and takes it out of the address bar at once
// (history.replaceState), so it is not shown over a shoulder, bookmarked or copied by accident. A later visit
// without the fragment uses the kept token. Every request of the page carries this token explicitly (not the
// workspace's), so two assignments open in two tabs never mix their identities.
import { request } from "../api.js";
import { store } from "../util.js";

const keyOf = (aid) => `rt.course.${aid}.token`;

/** The assignment's id from the address (/assignments/<id>), or null. */
export function assignmentId(pathname = location.pathname) {
  const m = /^\/assignments\/([^/]+)\/?$/.exec(pathname);
  return m ? decodeURIComponent(m[1]) : null;
}

/** The token of this visit: the link's (kept, and removed from the address bar), else the one kept from an
 * earlier visit; {token, from: "link" | "kept" | null}. */
export function linkToken(aid) {
  const params = new URLSearchParams(location.hash.slice(1));
  const fromLink = params.get("token");
  if (location.hash) history.replaceState(null, "", location.pathname + location.search);
  if (fromLink) {
    keep(aid, fromLink);
    return { token: fromLink, from: "link" };
  }
  const kept = store.get(keyOf(aid), null);
  return typeof kept === "string" && kept ? { token: kept, from: "kept" } : { token: null, from: null };
}

export function keep(aid, token) {
  store.set(keyOf(aid), token);
}

export function forget(aid) {
  try {
    localStorage.removeItem(keyOf(aid));
  } catch {
    // a private window without storage: nothing was kept
  }
}

/** The student's routes of one assignment, each request with `token`. */
export function studentApi(aid, token) {
  const base = `/api/assignments/${encodeURIComponent(aid)}`;
  const opts = { token, cache: "no-store" };
  return {
    base,
    token,
    brief: () => request("GET", base, undefined, opts),
    check: (body) => request("POST", `${base}/check`, body, opts),
    submit: (body) => request("POST", `${base}/submissions`, body, opts),
    submissions: () => request("GET", `${base}/submissions`, undefined, opts),
    submission: (sid) => request("GET", `${base}/submissions/${encodeURIComponent(sid)}`, undefined, opts),
    eventsUrl: (sid) => `${base}/submissions/${encodeURIComponent(sid)}/events`,
  };
}

/** POST .../join (an open assignment): {id, name, token, link, self_declared}. */
export function join(aid, name) {
  return request("POST", `/api/assignments/${encodeURIComponent(aid)}/join`, { name }, { token: null });
}
