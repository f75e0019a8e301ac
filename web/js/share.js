// Scenes in links: a scene's JSON text, deflated (CompressionStream) and written in base64url, so that it fits
// in a link's fragment (#scene/<data>). A fragment never reaches a server, so the scene is sent to no one.

export const MAX_LINK = 32_000; // characters of a whole link: past it, saving the scene as a file is the way
const MAX_TEXT = 2_000_000; // a scene's text at most (the server's request limit): a longer one is a broken link

function toBase64url(bytes) {
  let bin = "";
  for (let i = 0; i < bytes.length; i += 0x8000) bin += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(bin).replaceAll("+", "-").replaceAll("/", "_").replace(/=+$/, "");
}

function fromBase64url(text) {
  if (!/^[A-Za-z0-9_-]*$/.test(text)) throw new Error("the link has characters a scene's data never has");
  let bin;
  try {
    bin = atob(text.replaceAll("-", "+").replaceAll("_", "/") + "===".slice((text.length + 3) % 4));
  } catch {
    throw new Error("the link is cut short or damaged"); // a length base64 never has
  }
  return Uint8Array.from(bin, (c) => c.charCodeAt(0));
}

/** A scene's text as a link's data. */
export async function encodeScene(text) {
  const stream = new Blob([text]).stream().pipeThrough(new CompressionStream("deflate-raw"));
  return toBase64url(new Uint8Array(await new Response(stream).arrayBuffer()));
}

/** A link's data as the scene's text; throws an Error that says what is wrong with it. */
export async function decodeScene(data) {
  if (!data) throw new Error("the link holds no scene");
  let bytes;
  try {
    bytes = fromBase64url(data);
  } catch (err) {
    throw new Error(err.message.startsWith("the link") ? err.message : "the link's data is not base64url");
  }
  const reader = new Blob([bytes])
    .stream()
    .pipeThrough(new DecompressionStream("deflate-raw"))
    .pipeThrough(new TextDecoderStream())
    .getReader();
  let text = "";
  try {
    for (;;) {
      const { value, done } = await reader.read();
      if (done) break;
      text += value;
      if (text.length > MAX_TEXT) throw new Error(`the scene is over ${MAX_TEXT / 1e6} MB`);
    }
  } catch (err) {
    reader.cancel().catch(() => {});
    throw new Error(err.message.startsWith("the scene") ? err.message : "the link is cut short or damaged");
  }
  try {
    JSON.parse(text);
  } catch {
    throw new Error("the link's scene is not JSON");
  }
  return text;
}
