// LTI Platform Storage (the LTI client-side postMessages, docs/lti.md): where an LMS frames the tool and its
// browser keeps no cookie for the tool, the login's state is kept in the LMS's own page instead, and the launch
// checks it there before it opens anything. The pages are server/api/routes/lti.py's; their data-* attributes
// say what to do:
// - data-mode="put": put state and nonce into the platform's storage (lti.put_data), then go to the platform's
//   authentication request (data-next), answered or not (a platform without storage: the server's one-time
//   state stands);
// - data-mode="get": read the state back (lti.get_data); the same state: send the launch on (the form); another:
//   refuse; no answer: say so.
const el = document.getElementById("lti-storage");
const d = el.dataset;
const WAIT_MS = 3000; // how long the platform's page may take to answer

function frame() {
  try {
    return d.target === "_parent" ? window.parent : window.parent.frames[d.target] || window.parent;
  } catch {
    return window.parent;
  }
}

/** Send one message to the platform's storage frame; its answer (or null after WAIT_MS). */
function ask(subject, fields) {
  const id = `${subject}-${Math.random().toString(36).slice(2)}`;
  return new Promise((resolve) => {
    const timer = setTimeout(() => {
      window.removeEventListener("message", on);
      resolve(null);
    }, WAIT_MS);
    function on(event) {
      if (event.origin !== d.origin || !event.data || event.data.message_id !== id) return;
      if (event.data.subject !== `${subject}.response`) return;
      clearTimeout(timer);
      window.removeEventListener("message", on);
      resolve(event.data);
    }
    window.addEventListener("message", on);
    frame().postMessage({ subject, message_id: id, ...fields }, d.origin);
  });
}

function say(text) {
  const p = document.getElementById("lti-storage-status");
  p.textContent = text;
  p.dataset.kind = "error";
}

async function put() {
  await ask("lti.put_data", { key: `state_${d.state}`, value: d.state });
  await ask("lti.put_data", { key: `nonce_${d.nonce}`, value: d.nonce });
  window.location.replace(d.next);
}

async function get() {
  const answer = await ask("lti.get_data", { key: `state_${d.state}` });
  if (answer === null)
    return say(
      "Your learning platform did not answer the sign-in check: open the link again from your course (or in a new window).",
    );
  if (answer.value !== d.state) {
    document.querySelector("main").dataset.check = "state";
    return say(
      "state: this launch is not the one this browser's login started (platform storage); open the link again from your course.",
    );
  }
  document.getElementById("lti-continue").submit();
}

if (window.parent === window) {
  // not framed: no platform page to ask (a login offered storage, then opened in a tab of its own)
  if (d.mode === "put") window.location.replace(d.next);
  else say("This sign-in needs your learning platform's page: open the link again from your course.");
} else if (d.mode === "put") put();
else get();
