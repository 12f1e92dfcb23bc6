// The experimenter's live view: every session of this server, its running trial with the
// mode (shown here, never to the participant), timing, the robot on its map, an abort.
import * as M from "./messages.js";
import * as R from "./render.js";

const token = new URLSearchParams(location.search).get("token");
const maps = {}; // code -> {map, canvas}
let pendingMap = null;
const ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws-experimenter?token=${encodeURIComponent(token)}`);
ws.binaryType = "arraybuffer";
window.__asa_experimenter = { sessions: [] };

ws.onmessage = (e) => {
  if (typeof e.data !== "string") {
    if (pendingMap) { const map = M.unpackMap(e.data); maps[pendingMap] = { map, image: R.mapImage(map) }; }
    pendingMap = null;
    return;
  }
  const m = JSON.parse(e.data);
  if (m.type === "map") pendingMap = m.code;
  else if (m.type === "sessions") show(m);
};
ws.onclose = () => { document.getElementById("summary").textContent = "Disconnected from the server."; };

function cell(row, value) { const td = document.createElement("td"); td.textContent = value ?? ""; row.appendChild(td); }

function show(m) {
  window.__asa_experimenter = m;
  const running = m.sessions.filter((s) => s.running).length;
  document.getElementById("summary").textContent =
    `${running} running, ${m.sessions.length} in all; refused links: ${m.refused.bad_token}, study full: ${m.refused.full}`;
  const body = document.getElementById("rows");
  body.replaceChildren();
  const box = document.getElementById("maps");
  box.replaceChildren();
  for (const s of m.sessions) {
    const row = document.createElement("tr");
    const t = s.trial;
    cell(row, s.code); cell(row, s.connected ? (s.lost ? "lost" : "yes") : "no");
    cell(row, t ? t.phase : s.ended ? "ended" : "page"); cell(row, s.title || "");
    cell(row, t ? t.mode : ""); cell(row, s.t !== undefined ? `${s.t} s` : "");
    cell(row, `${s.elapsed_s} s`); cell(row, s.rtt_ms != null ? `${s.rtt_ms} ms` : "");
    cell(row, s.age != null ? `${s.age} ticks` : ""); cell(row, s.collisions ?? "");
    cell(row, Object.entries(s.drops).map(([k, v]) => `${k} ${v}`).join(", "));
    const td = document.createElement("td");
    if (s.running) {
      const b = document.createElement("button");
      b.textContent = "Abort";
      b.onclick = () => { if (confirm(`Abort the session of ${s.code}?`)) ws.send(JSON.stringify({ type: "abort", code: s.code })); };
      td.appendChild(b);
    }
    row.appendChild(td);
    body.appendChild(row);
    if (maps[s.code] && s.pose) box.appendChild(robotOnMap(s, maps[s.code]));
  }
}

function robotOnMap(s, { map, image }) {
  const c = document.createElement("canvas"), k = 240 / Math.max(map.cols, map.rows);
  c.width = map.cols * k; c.height = map.rows * k + 20;
  const ctx = c.getContext("2d");
  ctx.drawImage(image, 0, 20, map.cols * k, map.rows * k);
  const px = ((s.pose[0] - map.origin[0]) / map.resolution) * k;
  const py = 20 + map.rows * k - ((s.pose[1] - map.origin[1]) / map.resolution) * k;
  ctx.fillStyle = R.C.robot; ctx.beginPath(); ctx.arc(px, py, 5, 0, 2 * Math.PI); ctx.fill();
  ctx.strokeStyle = "white"; ctx.beginPath(); ctx.moveTo(px, py);
  ctx.lineTo(px + 10 * Math.cos(s.pose[2]), py - 10 * Math.sin(s.pose[2])); ctx.stroke();
  ctx.fillStyle = "#eee"; ctx.font = "14px sans-serif"; ctx.fillText(s.code, 4, 14);
  return c;
}
