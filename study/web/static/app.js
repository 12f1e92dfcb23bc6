// The participant's page: one WebSocket to the study server (and nothing else), the
// screens drawn by render.js from the server's descriptions, the gamepad (Gamepad API,
// standard mapping) and the keyboard sent back as INPUT messages (messages.js).
import * as M from "./messages.js";
import * as R from "./render.js";

const token = location.pathname.split("/").pop();
const canvas = document.getElementById("screen");
const ctx = canvas.getContext("2d");
const A = (window.__asa = {
  frames: 0, fps: 0, ticks: 0, screens: [], ws: null, phase: "connecting", lastTick: 0,
});
const view = { screen: null, state: null, strip: {}, camera: { front: null, tail: null },
  map: null, mapCanvas: null, scene: null };
let keymap = {}, held = new Set(), seq = 0, drawnTick = 0, sentTick = -1, hits = [];
let lastSent = "", message = null, retry = 0, gamepadPressed = false, checkWanted = null;

function connect() {
  const ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws/${token}`);
  ws.binaryType = "arraybuffer";
  A.ws = ws;
  ws.onopen = () => { retry = 0; send({ type: "hello" }); };
  ws.onmessage = (e) => (typeof e.data === "string" ? onJson(JSON.parse(e.data)) : onBinary(e.data));
  ws.onclose = (e) => {
    if (A.ws !== ws) return;
    A.ws = null;
    if (e.code === 4001 || A.phase === "ended" || A.phase === "refused") return;
    message = { title: "Connection lost", body: "Reconnecting ..." };
    setTimeout(connect, Math.min(5000, 500 * ++retry));
  };
}

function send(obj) {
  if (A.ws && A.ws.readyState === 1) A.ws.send(typeof obj === "object" && !(obj instanceof ArrayBuffer) ? JSON.stringify(obj) : obj);
}

function onJson(m) {
  if (m.type === "hello") keymap = m.keys;
  else if (m.type === "screen") {
    view.screen = m.screen; message = null; A.phase = m.screen.kind; A.screen = m.screen;
    A.screens.push(m.screen.kind);
    if (m.screen.kind === "drive") { view.state = null; view.camera = { front: null, tail: null }; }
  } else if (m.type === "strip") { view.strip = m; A.strip = m; }
  else if (m.type === "scene") view.scene = m;
  else if (m.type === "ping") send({ type: "pong", id: m.id });
  else if (m.type === "check") { checkWanted = m; A.phase = "check"; runCheck(); }
  else if (m.type === "refused") { A.phase = "refused"; message = { title: "Sorry, this computer cannot take part", body: m.reasons.join("\n\n") + "\n\nYou can fix this and open your link again." }; }
  else if (m.type === "end") { A.phase = "ended"; A.end = m; endPage(m); }
  else if (m.type === "aborted") { A.phase = "aborted"; message = { title: "The session has stopped", body: `${m.reason}.\n\nOpen your link again to continue where you stopped.` }; }
  else if (m.type === "taken_over") { A.phase = "taken_over"; message = { title: "Opened elsewhere", body: "This study was opened in another tab or window; continue there." }; }
}

function onBinary(buffer) {
  const kind = M.kindOf(buffer);
  if (kind === M.STATE) {
    view.state = M.unpackState(buffer); A.ticks++; A.lastTick = view.state.tick;
  } else if (kind === M.CAMERA) {
    const c = M.unpackCamera(buffer);
    createImageBitmap(new Blob([c.jpeg], { type: "image/jpeg" })).then((img) => {
      if (view.camera[c.which]) view.camera[c.which].close();
      view.camera[c.which] = img;
      A.cameraFrames = (A.cameraFrames || 0) + 1;
    });
  } else if (kind === M.MAP) {
    view.map = M.unpackMap(buffer); view.mapCanvas = R.mapImage(view.map);
  }
}

function endPage(m) {
  let body = "Your answers are stored. Thank you for taking part.";
  if (m.status === "excluded") body = "This session has ended. Thank you for your time.";
  if (m.code) body += `\n\nYour completion code: ${m.code}`;
  message = { title: "Finished", body };
  if (m.url) setTimeout(() => location.assign(m.url + (m.code ? `?cc=${encodeURIComponent(m.code)}` : "")), 3000);
}

// ------------------------------------------------------------------ the browser check

function runCheck() {
  const report = () => send({
    type: "check", width: innerWidth, height: innerHeight, gamepad: gamepadPressed,
    mobile: /Mobi|Android|iPad|iPhone/i.test(navigator.userAgent) || (navigator.maxTouchPoints > 1 && !matchMedia("(pointer: fine)").matches),
    agent: navigator.userAgent,
  });
  if (!checkWanted.gamepad || gamepadPressed) { message = { title: "Checking your connection ...", body: "" }; report(); return; }
  message = { title: "Your gamepad", body: "Please press any button on your gamepad." };
  const wait = () => (gamepadPressed ? runCheck() : setTimeout(wait, 50));
  wait();
}

// ------------------------------------------------------------------ input

const STD = { Enter: "enter", " ": "enter", ArrowUp: "arrow_up", ArrowDown: "arrow_down",
  ArrowLeft: "arrow_left", ArrowRight: "arrow_right" };

function keyName(e) {
  if (STD[e.key]) return STD[e.key];
  const letter = e.key.length === 1 ? e.key.toUpperCase() : "";
  for (const [action, key] of Object.entries(keymap)) if (key.toUpperCase() === letter) return action;
  return null;
}

addEventListener("keydown", (e) => {
  if (view.screen && view.screen.kind === "form" && (/^[0-9]$/.test(e.key) || e.key === "Backspace")) {
    send({ type: "key", key: e.key }); e.preventDefault(); return;
  }
  const name = keyName(e);
  if (name) { held.add(name); e.preventDefault(); sendInput(true); }
});
addEventListener("keyup", (e) => { const name = keyName(e); if (name) { held.delete(name); sendInput(true); } });
addEventListener("blur", () => { held.clear(); send({ type: "focus", focused: false }); sendInput(true); });
addEventListener("focus", () => send({ type: "focus", focused: true }));
document.addEventListener("visibilitychange", () => send({ type: "visibility", hidden: document.hidden }));
canvas.addEventListener("mousedown", (e) => {
  const r = canvas.getBoundingClientRect(), x = e.clientX - r.left, y = e.clientY - r.top;
  const hit = hits.find((h) => x >= h.x && x <= h.x + h.w && y >= h.y && y <= h.y + h.h);
  if (!hit) return;
  const click = { ...hit.click };
  if (hit.fraction) click.fraction = Math.min(1, Math.max(0, (x - hit.fraction[0]) / hit.fraction[1]));
  send(click);
});

function pad() {
  const pads = navigator.getGamepads ? navigator.getGamepads() : [];
  for (const p of pads) if (p && p.connected && p.mapping === "standard") return p;
  return null;
}

function sendInput(force) {
  const p = pad();
  let buttons = 0;
  const axes = [0, 0, 0, 0];
  if (p) {
    p.buttons.slice(0, 16).forEach((b, i) => { if (b.pressed) buttons |= 1 << i; });
    for (let i = 0; i < 4; i++) axes[i] = Math.max(-1, Math.min(1, p.axes[i] || 0));
    if (buttons) gamepadPressed = true;
  }
  let keys = 0;
  M.KEYS.forEach((k, i) => { if (held.has(k)) keys |= 1 << i; });
  const key = `${buttons}|${keys}|${axes.map((a) => a.toFixed(3)).join(",")}|${!!p}`;
  if (!force && key === lastSent && drawnTick === sentTick) return;
  lastSent = key; sentTick = drawnTick;
  if (A.ws && A.ws.readyState === 1) A.ws.send(M.packInput(++seq, drawnTick, axes, buttons, keys, !!p));
}

// ------------------------------------------------------------------ drawing

function resize() {
  const dpr = devicePixelRatio || 1;
  canvas.width = Math.round(innerWidth * dpr); canvas.height = Math.round(innerHeight * dpr);
  canvas.style.width = `${innerWidth}px`; canvas.style.height = `${innerHeight}px`;
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
}
addEventListener("resize", resize);

function draw() {
  const w = innerWidth, h = innerHeight;
  if (message || !view.screen) {
    hits = R.drawPage(ctx, { title: message ? message.title : "Connecting ...", body: message ? message.body : "", prompt: "", legend: [] }, w, h);
    hits = [];
  } else if (view.screen.kind === "page") hits = R.drawPage(ctx, view.screen, w, h);
  else if (view.screen.kind === "form") hits = R.drawForm(ctx, view.screen, w, h);
  else if (view.screen.kind === "pair") hits = R.drawPair(ctx, view.screen, w, h);
  else if (view.screen.kind === "drive") { R.drawDrive(ctx, view, w, h); hits = []; }
  if (view.state) drawnTick = view.state.tick;
}

let fpsStart = performance.now(), fpsFrames = 0;
function frame(now) {
  draw();
  sendInput(false);
  A.frames++; fpsFrames++;
  if (now - fpsStart >= 1000) { A.fps = (fpsFrames * 1000) / (now - fpsStart); fpsStart = now; fpsFrames = 0; }
  requestAnimationFrame(frame);
}

resize();
connect();
requestAnimationFrame(frame);
