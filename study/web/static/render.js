// The browser's renderer of the participant's screens: it draws the descriptions of
// study/ui/describe.py (page, form, pair, drive) on a canvas, laid out as the pygame
// window lays them out (study/ui/screen.py, form_view.py, map_view.py, legend.py), in
// the same colours. Returns the click targets of what it drew.
export const C = {
  background: "rgb(32,34,40)", panel: "rgb(48,52,60)", text: "rgb(235,235,235)",
  dim: "rgb(150,150,150)", yes: "rgb(40,140,70)", no: "rgb(170,50,50)",
  highlight: "rgb(240,190,40)", free: "rgb(250,250,250)", occupied: "rgb(70,70,70)",
  region: "rgb(255,244,190)", robot: "rgb(40,90,200)", laser: "rgb(170,40,210)",
  arrow: "rgb(20,170,60)", goal: "rgb(0,140,150)", cap: "rgb(70,76,88)", label: "rgb(160,160,160)",
};
const CELL_RGB = [[250, 250, 250], [255, 244, 190], [70, 70, 70]];

export function fonts(h) {
  return {
    legend: Math.max(14, Math.round(h / 40)), small: Math.max(14, Math.round(h / 36)),
    body: Math.max(17, Math.round(h / 29)), large: Math.max(22, Math.round(h / 19)),
  };
}

function font(ctx, px) { ctx.font = `${px}px sans-serif`; }

function text(ctx, value, x, y, px, colour = C.text, align = "left", base = "top") {
  font(ctx, px); ctx.fillStyle = colour; ctx.textAlign = align; ctx.textBaseline = base;
  ctx.fillText(value, x, y);
  return ctx.measureText(value).width;
}

export function wrap(ctx, value, width, px) {
  font(ctx, px);
  const lines = [];
  for (const paragraph of value.split("\n")) {
    let line = "";
    for (const word of paragraph.split(/\s+/).filter(Boolean)) {
      const trial = line ? `${line} ${word}` : word;
      if (ctx.measureText(trial).width <= width || !line) line = trial;
      else { lines.push(line); line = word; }
    }
    lines.push(line);
  }
  return lines;
}

function paragraph(ctx, value, x, y, width, px, colour = C.text) {
  const step = Math.round(px * 1.2);
  for (const line of wrap(ctx, value, width, px)) {
    if (line) text(ctx, line, x, y, px, colour);
    y += step;
  }
  return y;
}

function rrect(ctx, x, y, w, h, r, fill, stroke, lw = 2) {
  ctx.beginPath(); ctx.roundRect(x, y, w, h, r);
  if (fill) { ctx.fillStyle = fill; ctx.fill(); }
  if (stroke) { ctx.strokeStyle = stroke; ctx.lineWidth = lw; ctx.stroke(); }
}

export function legendHeight(f) { return 2 * (Math.round(f.legend * 1.2) + 10) + 8; }

export function drawLegend(ctx, legend, w, h, f) {
  if (!legend || !legend.length) return;
  const top = h - legendHeight(f), step = Math.round(f.legend * 1.2) + 10;
  ctx.fillStyle = C.background; ctx.fillRect(0, top, w, h - top);
  ctx.fillStyle = C.panel; ctx.fillRect(0, top, w, 2);
  let y = top + 4;
  for (const [device, entries] of legend) {
    font(ctx, f.legend);
    const parts = [[`${device}:`, false]];
    for (const [control, action] of entries) parts.push([control, true], [action, false]);
    const widths = parts.map(([t]) => ctx.measureText(t).width);
    const total = widths.reduce((a, b, i) => a + b + (parts[i][1] ? 22 : 18), 0);
    let x = w / 2 - total / 2;
    parts.forEach(([t, cap], i) => {
      if (cap) rrect(ctx, x, y + step / 2 - f.legend * 0.75, widths[i] + 12, f.legend * 1.5, 5, C.cap);
      text(ctx, t, x + (cap ? 6 : 0), y + step / 2, f.legend, cap ? "rgb(245,245,245)" : C.label,
        "left", "middle");
      x += widths[i] + (cap ? 22 : 18);
    });
    y += step;
  }
}

export function drawPage(ctx, s, w, h) {
  const f = fonts(h);
  ctx.fillStyle = C.background; ctx.fillRect(0, 0, w, h);
  const margin = Math.round(w * 0.1);
  let y = Math.round(h * 0.1);
  if (s.title) { text(ctx, s.title, margin, y, f.large); y += Math.round(f.large * 2.4); }
  paragraph(ctx, s.body, margin, y, w - 2 * margin, f.body);
  if (s.prompt) text(ctx, s.prompt, w / 2, h - legendHeight(f) - f.body * 1.2, f.body,
    C.highlight, "center", "bottom");
  drawLegend(ctx, s.legend, w, h, f);
  return [{ x: 0, y: 0, w, h, click: { type: "click", target: "page" } }];
}

function rowHeight(ctx, row, width, f) {
  const lines = wrap(ctx, row.label, width, f.small).length;
  let widget = Math.round(f.legend * 1.2) + 18;
  if (row.kind === "slider") widget = 36;
  else if (row.kind !== "number") {
    const n = row.options.length, ow = (width - 8 * (n - 1)) / n;
    widget = Math.max(...row.options.map((o) => wrap(ctx, o, ow - 12, f.legend).length))
      * Math.round(f.legend * 1.2) + 14;
  }
  return 16 + lines * Math.round(f.small * 1.2) + 4 + widget;
}

function formFit(ctx, s, w, h) {
  // the largest fonts (down to 60 %) with which every row fits above "Done"
  const margin = Math.round(w * 0.06);
  for (let k = 1.0; ; k -= 0.08) {
    const f = fonts(h * k), legend = fonts(h);
    const line = Math.round(f.small * 1.2);
    const top = Math.round(h * 0.03) + Math.round(f.large * 1.2)
      + wrap(ctx, s.instructions, w - 2 * margin, f.small).length * line + 4;
    const heights = s.rows.map((r) => rowHeight(ctx, r, w - 2 * margin, f));
    const bottom = h - legendHeight(legend) - 8 - Math.round(h * 0.065) - line * 3;
    if (top + heights.reduce((a, b) => a + b, 0) + 2 * heights.length <= bottom || k < 0.64) {
      return { f: { ...f, legendBar: legend }, heights };
    }
  }
}

export function drawForm(ctx, s, w, h) {
  const { f, heights } = formFit(ctx, s, w, h), hits = [];
  ctx.fillStyle = C.background; ctx.fillRect(0, 0, w, h);
  const margin = Math.round(w * 0.06), line = Math.round(f.small * 1.2);
  let y = Math.round(h * 0.03);
  text(ctx, s.title, margin, y, f.large); y += Math.round(f.large * 1.2);
  y = paragraph(ctx, s.instructions, margin, y, w - 2 * margin, f.small, C.dim) + 4;
  const done = { w: Math.round(w * 0.18), h: Math.round(h * 0.065) };
  done.x = w / 2 - done.w / 2; done.y = h - legendHeight(f.legendBar) - 8 - done.h;
  const spare = done.y - line * 3 - y - heights.reduce((a, b) => a + b, 0);
  const gap = Math.max(2, Math.min(14, Math.floor(spare / Math.max(1, heights.length))));
  s.rows.forEach((row, k) => {
    const fx = margin - 8, fw = w - 2 * margin + 16, fh = heights[k];
    if (k === s.row) rrect(ctx, fx, y, fw, fh, 6, C.panel, C.highlight);
    hits.push({ x: fx, y, w: fw, h: fh, click: { type: "click", target: "row", row: k } });
    const wy = paragraph(ctx, row.label, margin, y + 8, w - 2 * margin, f.small) + 4;
    drawWidget(ctx, row, k, k === s.row, s.hint, margin, wy, w - 2 * margin, y + fh - 8 - wy, f, hits);
    y += fh + gap;
  });
  const desc = s.description ? wrap(ctx, s.description, w - 2 * margin, f.small) : [];
  for (const l of desc) {
    if (y + line > done.y - line - 8) break;
    text(ctx, l, margin, y, f.small, C.dim); y += line;
  }
  const active = s.row === s.rows.length;
  rrect(ctx, done.x, done.y, done.w, done.h, 8, active ? C.highlight : C.panel);
  text(ctx, "Done", w / 2, done.y + done.h / 2, f.body, active ? C.background : C.text, "center", "middle");
  hits.push({ ...done, click: { type: "click", target: "done" } });
  if (s.reminder) text(ctx, s.reminder, w / 2, done.y - 6, f.small, C.highlight, "center", "bottom");
  drawLegend(ctx, s.legend, w, h, f.legendBar);
  return hits.reverse(); // options before their rows
}

function chip(ctx, x, y, w, h, lines, on, f) {
  rrect(ctx, x, y, w, h, 6, on ? C.highlight : C.panel, on ? C.highlight : C.dim, 1);
  const step = Math.round(f.legend * 1.2);
  let ty = y + h / 2 - (lines.length * step) / 2;
  for (const l of lines) {
    text(ctx, l, x + w / 2, ty, f.legend, on ? C.background : C.text, "center"); ty += step;
  }
}

function drawWidget(ctx, row, k, selected, hint, x, y, width, height, f, hits) {
  if (row.kind === "slider") {
    const left = x + width * 0.2, right = x + width * 0.8, cy = y + height / 2, n = row.scale;
    ctx.strokeStyle = C.text; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.moveTo(left, cy); ctx.lineTo(right, cy); ctx.stroke();
    ctx.lineWidth = 1;
    for (let i = 0; i < n && n <= 25; i++) {
      const tx = left + ((right - left) * i) / Math.max(1, n - 1), tall = i % 2 ? 5 : 8;
      ctx.beginPath(); ctx.moveTo(tx, cy - tall); ctx.lineTo(tx, cy + tall); ctx.stroke();
    }
    if (row.anchors.length) {
      text(ctx, row.anchors[0], left - 12, cy, f.small, C.text, "right", "middle");
      text(ctx, row.anchors[1], right + 12, cy, f.small, C.text, "left", "middle");
    }
    if (row.chosen !== null) {
      ctx.fillStyle = C.highlight; ctx.beginPath();
      ctx.arc(left + ((right - left) * row.chosen) / Math.max(1, n - 1), cy, 9, 0, 2 * Math.PI); ctx.fill();
    }
    hits.push({ x: left - 10, y: cy - 17, w: right - left + 20, h: 34,
      fraction: [left, right - left], click: { type: "click", target: "fraction", row: k } });
    return;
  }
  if (row.kind === "number") {
    const bw = Math.max(90, width / 10);
    rrect(ctx, x, y, bw, height, 4, C.background, selected ? C.highlight : C.dim);
    const shown = row.typed + (selected ? "|" : "");
    if (shown) text(ctx, shown, x + bw / 2, y + height / 2, f.small, C.text, "center", "middle");
    let nx = x + bw + 10 + text(ctx, row.unit, x + bw + 10, y + height / 2, f.small, C.text, "left", "middle") + 24;
    row.options.forEach((label, i) => {
      font(ctx, f.legend);
      const cw = ctx.measureText(label).width + 24;
      chip(ctx, nx, y, cw, height, [label], row.declined, f);
      hits.push({ x: nx, y, w: cw, h: height, click: { type: "click", target: "option", row: k, index: i } });
      nx += cw + 24;
    });
    const shownHint = row.problem || (selected ? hint : "");
    if (shownHint) text(ctx, shownHint, nx, y + height / 2, f.legend, row.problem ? C.highlight : C.dim, "left", "middle");
    return;
  }
  const n = row.options.length, ow = (width - 8 * (n - 1)) / n;
  row.options.forEach((label, i) => {
    const ox = x + i * (ow + 8);
    chip(ctx, ox, y, ow, height, wrap(ctx, label, ow - 12, f.legend), row.chosen === i, f);
    hits.push({ x: ox, y, w: ow, h: height, click: { type: "click", target: "option", row: k, index: i } });
  });
}

export function drawPair(ctx, s, w, h) {
  const f = fonts(h), hits = [];
  ctx.fillStyle = C.background; ctx.fillRect(0, 0, w, h);
  text(ctx, s.question, w / 2, h * 0.1, f.large, C.text, "center", "middle");
  text(ctx, s.progress, w / 2, h * 0.17, f.small, C.dim, "center", "middle");
  const bottom = h - legendHeight(f) - 16;
  for (let i = 0; i < 2; i++) {
    const rw = w * 0.4, rh = Math.min(h * 0.5, bottom - h * 0.24);
    const x = w * (0.28 + 0.44 * i) - rw / 2, y = h * 0.24, on = s.highlight === i;
    rrect(ctx, x, y, rw, rh, 10, C.panel, on ? C.highlight : C.dim, on ? 4 : 2);
    text(ctx, s.titles[i], x + rw / 2, y + 30, f.large, C.text, "center", "middle");
    paragraph(ctx, s.texts[i], x + 15, y + 75, rw - 30, f.small, C.dim);
    hits.push({ x, y, w: rw, h: rh, click: { type: "click", target: "pair", index: i } });
  }
  drawLegend(ctx, s.legend, w, h, f);
  return hits;
}

// ------------------------------------------------------------------ the driving screen

export function mapImage(map) {
  const canvas = document.createElement("canvas");
  canvas.width = map.cols; canvas.height = map.rows;
  const c = canvas.getContext("2d"), img = c.createImageData(map.cols, map.rows);
  for (let r = 0; r < map.rows; r++) {
    for (let col = 0; col < map.cols; col++) {
      const rgb = CELL_RGB[map.cells[r * map.cols + col]] || CELL_RGB[0];
      const o = ((map.rows - 1 - r) * map.cols + col) * 4; // y up
      img.data[o] = rgb[0]; img.data[o + 1] = rgb[1]; img.data[o + 2] = rgb[2]; img.data[o + 3] = 255;
    }
  }
  c.putImageData(img, 0, 0);
  return canvas;
}

export function driveLayout(s, w, h) {
  const f = fonts(h), top = Math.round(h * 0.09), legendTop = h - legendHeight(f);
  const bottom = s.questions ? Math.round(h * 0.18) : 0;
  const mid = { x: 0, y: top, w, h: legendTop - bottom - top };
  const inset = (r) => ({ x: r.x + 6, y: r.y + 6, w: r.w - 12, h: r.h - 12 });
  const out = { f, top, question: { x: 0, y: mid.y + mid.h, w, h: bottom } };
  if (s.layout === "laser") {
    const split = Math.round(w * 0.55), half = Math.round(mid.h / 2);
    out.laser = inset({ x: 0, y: mid.y, w: split, h: mid.h });
    out.camera = inset({ x: split, y: mid.y, w: w - split, h: half });
    out.tail = inset({ x: split, y: mid.y + half, w: w - split, h: mid.h - half });
  } else if (s.show_map) {
    out.camera = inset({ x: 0, y: mid.y, w: Math.floor(w / 2), h: mid.h });
    out.map = inset({ x: Math.floor(w / 2), y: mid.y, w: w - Math.floor(w / 2), h: mid.h });
  } else out.camera = inset(mid);
  return out;
}

function fit(ctx, value, width, px) {
  font(ctx, px);
  if (ctx.measureText(value).width <= width) return value;
  const words = value.split(" ");
  while (words.length && ctx.measureText(words.join(" ") + " ...").width > width) words.pop();
  return words.join(" ") + " ...";
}

export function drawDrive(ctx, view, w, h) {
  const s = view.screen, L = driveLayout(s, w, h), f = L.f, st = view.state;
  ctx.fillStyle = C.background; ctx.fillRect(0, 0, w, h);
  ctx.fillStyle = C.panel; ctx.fillRect(0, 0, w, L.top);
  const pad = Math.round(L.top / 8), t = st ? st.t : 0;
  const clock = `${Math.floor(t / 60)}:${String(Math.floor(t % 60)).padStart(2, "0")}`;
  const cw = text(ctx, clock, w - 12, pad, f.small, C.dim, "right");
  let x = 12;
  if (s.title) x += text(ctx, s.title, x, pad, f.small, C.highlight) + 16;
  if (s.reminder) text(ctx, fit(ctx, s.reminder, w - cw - 28 - x, f.small), x, pad, f.small);
  const strip = view.strip || {};
  if (strip.feedback) text(ctx, strip.feedback, 12, pad + f.small * 1.2 + 4, f.small, C.highlight);
  camera(ctx, view.camera.front, L.camera, f);
  if (L.tail) camera(ctx, view.camera.tail, L.tail, f);
  if (L.map && view.map) drawMap(ctx, view, L.map, f);
  if (L.laser) drawLaser(ctx, view, L.laser);
  if (s.questions) drawQuestion(ctx, s, strip, L.question, w, f);
  drawLegend(ctx, s.legend, w, h, f);
  if (strip.overlay) {
    const bw = w * 0.7, bh = h * 0.3, bx = (w - bw) / 2, by = (h - bh) / 2;
    rrect(ctx, bx, by, bw, bh, 12, C.panel, C.highlight, 3);
    paragraph(ctx, strip.overlay, bx + 20, by + 20, bw - 40, f.large);
  }
}

function camera(ctx, image, r, f) {
  if (!image) {
    ctx.fillStyle = C.panel; ctx.fillRect(r.x, r.y, r.w, r.h);
    text(ctx, "Camera starting ...", r.x + r.w / 2, r.y + r.h / 2, f.body, C.dim, "center", "middle");
    return;
  }
  const k = Math.min(r.w / image.width, r.h / image.height);
  const iw = image.width * k, ih = image.height * k;
  ctx.drawImage(image, r.x + (r.w - iw) / 2, r.y + (r.h - ih) / 2, iw, ih);
}

function mapFrame(view, r) {
  const m = view.map, k = Math.min(r.w / m.cols, r.h / m.rows);
  const iw = m.cols * k, ih = m.rows * k, left = r.x + (r.w - iw) / 2, top = r.y + (r.h - ih) / 2;
  const pxm = k / m.resolution;
  return { left, top, iw, ih, pxm, px: (x, y) => [left + (x - m.origin[0]) * pxm, top + ih - (y - m.origin[1]) * pxm] };
}

function toMap(pose, x, y) {
  const c = Math.cos(pose[2]), s = Math.sin(pose[2]);
  return [pose[0] + c * x - s * y, pose[1] + s * x + c * y];
}

function poly(ctx, pts, fill, stroke, lw = 1) {
  ctx.beginPath(); pts.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y))); ctx.closePath();
  if (fill) { ctx.fillStyle = fill; ctx.fill(); }
  if (stroke) { ctx.strokeStyle = stroke; ctx.lineWidth = lw; ctx.stroke(); }
}

function drawMap(ctx, view, r, f) {
  const M = mapFrame(view, r), s = view.screen, st = view.state;
  ctx.imageSmoothingEnabled = true;
  ctx.drawImage(view.mapCanvas, M.left, M.top, M.iw, M.ih);
  const obj = view.scene && view.scene.object;
  if (s.show_object && obj) {
    const col = `rgb(${obj.colour.join(",")})`;
    if (obj.shape === "cylinder") {
      const [cx, cy] = M.px(...obj.centre);
      ctx.beginPath(); ctx.arc(cx, cy, Math.max(4, obj.radius * M.pxm), 0, 2 * Math.PI);
      ctx.fillStyle = col; ctx.fill(); ctx.strokeStyle = "black"; ctx.lineWidth = 1; ctx.stroke();
    } else {
      const [hx, hy] = [obj.size[0] / 2, obj.size[1] / 2];
      const pts = [[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]].map(([a, b]) =>
        M.px(...toMap([...obj.centre, obj.yaw], a, b)));
      poly(ctx, pts, col, "black");
    }
  }
  const drawn = new Set();
  for (const g of s.goals) {
    const [cx, cy] = M.px(g.x, g.y), rad = Math.max(5, g.tolerance_m * M.pxm);
    ctx.beginPath(); ctx.arc(cx, cy, rad, 0, 2 * Math.PI); ctx.strokeStyle = C.goal; ctx.lineWidth = 2; ctx.stroke();
    if (g.yaw !== null) {
      const reach = rad + Math.max(8, 0.35 * M.pxm), wedge = [[cx, cy]];
      for (let i = 0; i < 9; i++) {
        const a = g.yaw - g.tolerance_rad + (2 * g.tolerance_rad * i) / 8;
        wedge.push([cx + reach * Math.cos(a), cy - reach * Math.sin(a)]);
      }
      poly(ctx, wedge, null, C.goal);
      ctx.beginPath(); ctx.moveTo(cx, cy); ctx.lineTo(cx + reach * Math.cos(g.yaw), cy - reach * Math.sin(g.yaw));
      ctx.lineWidth = 2; ctx.stroke();
    }
    text(ctx, g.label, cx, cy - rad - 1, f.small, "black", "center", "bottom");
    drawn.add(g.label);
  }
  for (const [label, x, y] of s.marks) {
    if (drawn.has(label)) continue;
    const [px, py] = M.px(x, y);
    text(ctx, label, px, py - 8, f.small, "black", "center", "bottom");
  }
  if (!st) return;
  ctx.save(); // hits beyond the map stay in its rectangle, as the pygame screen keeps them
  ctx.beginPath(); ctx.rect(r.x, r.y, r.w, r.h); ctx.clip();
  ctx.fillStyle = C.laser;
  for (let i = 0; i < st.points.length; i += 2) {
    const [px, py] = M.px(st.points[i] / 100, st.points[i + 1] / 100);
    ctx.beginPath(); ctx.arc(px, py, 2, 0, 2 * Math.PI); ctx.fill();
  }
  const fp = s.footprint;
  poly(ctx, fp.map(([a, b]) => M.px(...toMap(st.pose, a, b))), C.robot);
  const front = Math.max(...fp.map((p) => p[0])), back = Math.min(...fp.map((p) => p[0]));
  const half = Math.max(...fp.map((p) => p[1]));
  const arrow = [[front, 0], [back * 0.4, half * 0.75], [back * 0.1, 0], [back * 0.4, -half * 0.75]];
  poly(ctx, arrow.map(([a, b]) => M.px(...toMap(st.pose, a, b))), "white", "black");
  drawStick(ctx, st.pose, st.stick, M);
  ctx.restore();
}

function drawStick(ctx, pose, stick, M) {
  if (Math.hypot(stick[0], stick[1]) <= 0.02 && Math.abs(stick[2]) <= 0.02) return;
  const [ax, ay] = M.px(...toMap(pose, 0, 0)), [bx, by] = M.px(...toMap(pose, stick[0] * 0.9, stick[1] * 0.9));
  ctx.strokeStyle = C.arrow; ctx.lineWidth = 4;
  ctx.beginPath(); ctx.moveTo(ax, ay); ctx.lineTo(bx, by); ctx.stroke();
  const n = Math.hypot(bx - ax, by - ay);
  if (n > 3) {
    const dx = (bx - ax) / n, dy = (by - ay) / n;
    poly(ctx, [[bx, by], [bx - 10 * dx - 6 * dy, by - 10 * dy + 6 * dx], [bx - 10 * dx + 6 * dy, by - 10 * dy - 6 * dx]], C.arrow);
  }
  if (Math.abs(stick[2]) > 0.02) {
    const start = Math.PI / 2 - 0.2, span = stick[2] * Math.PI * 0.8;
    ctx.lineWidth = 3; ctx.beginPath();
    ctx.arc(ax, ay, 18, -Math.max(start, start + span), -Math.min(start, start + span)); ctx.stroke();
  }
}

function drawLaser(ctx, view, r) {
  const st = view.state, s = view.screen;
  ctx.fillStyle = C.panel; ctx.fillRect(r.x, r.y, r.w, r.h);
  if (!st) return;
  const k = Math.min(r.w, r.h) / 2 / 6.0, cx = r.x + r.w / 2, cy = r.y + r.h / 2; // 6 m to the edge
  const c = Math.cos(-st.pose[2]), sn = Math.sin(-st.pose[2]);
  ctx.fillStyle = C.laser;
  for (let i = 0; i < st.points.length; i += 2) {
    const dx = st.points[i] / 100 - st.pose[0], dy = st.points[i + 1] / 100 - st.pose[1];
    const x = c * dx - sn * dy, y = sn * dx + c * dy;
    ctx.beginPath(); ctx.arc(cx - y * k, cy - x * k, 2, 0, 2 * Math.PI); ctx.fill();
  }
  poly(ctx, s.footprint.map(([a, b]) => [cx - b * k, cy - a * k]), C.robot);
}

function drawQuestion(ctx, s, strip, r, w, f) {
  ctx.fillStyle = C.panel; ctx.fillRect(r.x, r.y, r.w, r.h);
  const cy = r.y + r.h / 3, q = strip.question;
  if (q) text(ctx, q, w / 2, cy, f.large, C.text, "center", "middle");
  else text(ctx, "Questions appear here.", w / 2, cy, f.body, C.dim, "center", "middle");
  const bw = w * 0.2, bh = r.h * 0.34, by = r.y + (r.h * 3) / 4 - bh / 2;
  [[s.yes_label, w / 2 - (bw * 3) / 4, C.yes], [s.no_label, w / 2 + (bw * 3) / 4, C.no]].forEach(([label, bx, col]) => {
    rrect(ctx, bx - bw / 2, by, bw, bh, 8, q ? col : C.panel, q ? C.text : C.dim);
    text(ctx, label, bx, by + bh / 2, f.body, q ? C.text : C.dim, "center", "middle");
  });
  if (strip.confirmation) text(ctx, strip.confirmation, r.x + r.w - 20, by + bh / 2, f.body, C.highlight, "right", "middle");
}
