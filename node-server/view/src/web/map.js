// Ocelli live map: the floor plan (room, walls, head regions), each camera's field of view on
// the floor coloured by mode and marked when down (✕) or stale (?), each track with its global
// id, 2σ ellipse and 10 s trail, handovers flashed as they happen, and the tables beside it.
"use strict";

(() => {
  const SVG = "http://www.w3.org/2000/svg";
  const svg = document.getElementById("map");
  const layers = {
    static: document.getElementById("static"),
    cameras: document.getElementById("cameras"),
    tracks: document.getElementById("tracks"),
    flashes: document.getElementById("flashes"),
  };
  let view = null; // world → pixel mapping
  let worldKey = "";
  let lastHandover = null;
  let latest = null;

  function s(tag, attrs, text) {
    const e = document.createElementNS(SVG, tag);
    for (const k in attrs) e.setAttribute(k, attrs[k]);
    if (text !== undefined) e.textContent = text;
    return e;
  }

  // Fit the room into the SVG with a margin, y up.
  function fit(world) {
    const w = svg.clientWidth || 800, h = svg.clientHeight || 600;
    const [x0, y0] = world.min, [x1, y1] = world.max;
    const pad = 40;
    const k = Math.min((w - 2 * pad) / Math.max(x1 - x0, 1e-3), (h - 2 * pad) / Math.max(y1 - y0, 1e-3));
    const ox = (w - k * (x1 - x0)) / 2, oy = (h - k * (y1 - y0)) / 2;
    return { k, px: (x) => ox + (x - x0) * k, py: (y) => oy + (y1 - y) * k };
  }

  const pt = (p) => view.px(p[0]).toFixed(1) + "," + view.py(p[1]).toFixed(1);

  function drawStatic(state) {
    const g = layers.static;
    g.replaceChildren();
    const [x0, y0] = state.world.min, [x1, y1] = state.world.max;
    g.appendChild(s("rect", { class: "room", x: view.px(x0), y: view.py(y1), width: (x1 - x0) * view.k, height: (y1 - y0) * view.k }));
    const grid = s("g", { class: "grid" });
    for (let x = Math.ceil(x0); x <= x1; x++) {
      grid.appendChild(s("line", { x1: view.px(x), y1: view.py(y0), x2: view.px(x), y2: view.py(y1) }));
      g.appendChild(s("text", { class: "axis", x: view.px(x), y: view.py(y0) + 16, "text-anchor": "middle" }, x + (x === Math.ceil(x0) ? " m" : "")));
    }
    for (let y = Math.ceil(y0); y <= y1; y++) {
      grid.appendChild(s("line", { x1: view.px(x0), y1: view.py(y), x2: view.px(x1), y2: view.py(y) }));
      g.appendChild(s("text", { class: "axis", x: view.px(x0) - 8, y: view.py(y) + 4, "text-anchor": "end" }, String(y)));
    }
    g.insertBefore(grid, g.children[1]);
    for (const n of state.nodes) {
      if (n.role !== "head" || !n.region) continue;
      const [a, b, c, d] = n.region;
      const colour = Ocelli.headColour(state, n.id);
      g.appendChild(s("rect", { class: "region", stroke: colour, x: view.px(a) + 3, y: view.py(d) + 3, width: (c - a) * view.k - 6, height: (d - b) * view.k - 6 }));
      g.appendChild(s("text", { class: "region-label", fill: colour, x: view.px(a) + 12, y: view.py(d) + 38 }, "head " + n.id + " region"));
    }
    for (const w of state.world.walls) {
      g.appendChild(s("line", { class: "wall", x1: view.px(w.from[0]), y1: view.py(w.from[1]), x2: view.px(w.to[0]), y2: view.py(w.to[1]) }));
    }
  }

  function drawCameras(state) {
    const wedges = s("g", {}), marks = s("g", {});
    // Cameras whose measurement or reading went into a track this step: their wedges stand out.
    const seeing = new Set(state.tracks.flatMap((t) => t.cameras.concat(t.rssi)));
    const nodes = [...state.nodes].sort((a, b) => seeing.has(a.id) - seeing.has(b.id));
    for (const n of nodes) {
      if (!n.camera) continue;
      const cls = Ocelli.modeClass(n);
      const wedge = cls + (seeing.has(n.id) ? " seeing" : "");
      wedges.appendChild(s("polygon", { class: "wedge " + wedge, points: n.camera.footprint.map(pt).join(" ") }));
      const [x, y] = [view.px(n.camera.position[0]), view.py(n.camera.position[1])];
      // A short stroke along the viewing direction.
      const f = n.camera.forward, len = Math.hypot(f[0], f[1]) || 1;
      marks.appendChild(s("line", { x1: x, y1: y, x2: x + (14 * f[0]) / len, y2: y - (14 * f[1]) / len, stroke: "#aeb8c8", "stroke-width": 1.5 }));
      const cam = s("circle", { class: "cam " + cls, cx: x, cy: y, r: 5.5, "data-camera": n.id });
      cam.appendChild(s("title", {}, "camera " + n.id + ": " + (n.up ? (n.mode || "mode unknown") : "down") + (n.stale ? ", stale" : "")));
      marks.appendChild(cam);
      marks.appendChild(s("text", { class: "cam-label", x: x + 7, y: y - 7 }, String(n.id)));
      if (!n.up) marks.appendChild(s("text", { class: "cam-mark down", x: x - 5, y: y + 20 }, "✕"));
      else if (n.stale) marks.appendChild(s("text", { class: "cam-mark stale", x: x - 4, y: y + 20 }, "?"));
    }
    layers.cameras.replaceChildren(wedges, marks);
  }

  function drawTracks(state) {
    const g = layers.tracks;
    g.replaceChildren();
    for (const t of state.tracks) {
      if (!t.updated_ns) continue;
      const colour = Ocelli.headColour(state, t.owner);
      const old = state.time_ns - t.updated_ns > 2e9;
      const tg = s("g", { class: "track" + (old ? " old" : ""), "data-global": t.global });
      if (t.trail.length > 1) {
        tg.appendChild(s("polyline", { class: "trail", stroke: colour, points: t.trail.map((p) => pt([p[1], p[2]])).join(" ") }));
      }
      const [x, y] = [view.px(t.position[0]), view.py(t.position[1])];
      if (t.ellipse) {
        const deg = (-t.ellipse.angle * 180) / Math.PI;
        tg.appendChild(s("ellipse", {
          class: "ellipse", fill: colour, stroke: colour, cx: x, cy: y,
          rx: Math.max(t.ellipse.semi_major * view.k, 2), ry: Math.max(t.ellipse.semi_minor * view.k, 2),
          transform: "rotate(" + deg.toFixed(2) + " " + x.toFixed(1) + " " + y.toFixed(1) + ")",
        }));
      }
      tg.appendChild(s("circle", { class: "track-dot", cx: x, cy: y, r: 6, fill: colour }));
      tg.appendChild(s("text", { class: "track-label", x: x + 10, y: y - 10 }, "t" + t.global));
      g.appendChild(tg);
    }
  }

  function flash(state) {
    const fresh = state.handovers.filter((h) => lastHandover !== null && h.seq > lastHandover);
    if (lastHandover === null) {
      // On first load only the ones from the last 3 s.
      fresh.push(...state.handovers.filter((h) => state.time - h.time < 3));
    }
    lastHandover = state.handovers.reduce((m, h) => Math.max(m, h.seq), lastHandover || 0);
    const toast = document.getElementById("toast");
    for (const h of fresh) {
      const t = state.tracks.find((t) => t.global === h.global);
      const p = t ? t.position : h.position;
      if (p) {
        const c = s("circle", { class: "flash", cx: view.px(p[0]), cy: view.py(p[1]), r: 26 });
        layers.flashes.appendChild(c);
        setTimeout(() => c.remove(), 1700);
      }
      const msg = Ocelli.el("div", {}, "handover t" + h.global + ": " + (h.from ? "head " + h.from : "—") + " → head " + h.to + " (" + h.reason.replace("_", " ") + ")");
      toast.appendChild(msg);
      setTimeout(() => msg.remove(), 4000);
    }
  }

  function cell(text, cls) {
    const td = Ocelli.el("td", cls ? { class: cls } : {}, text);
    return td;
  }

  function tables(state) {
    const rows = state.tracks.filter((t) => t.updated_ns).map((t) => {
      const tr = Ocelli.el("tr", { "data-global": t.global });
      tr.append(
        cell("t" + t.global), cell(String(t.owner)), cell(t.position[0].toFixed(2)), cell(t.position[1].toFixed(2)),
        cell(t.ellipse ? t.ellipse.semi_major.toFixed(2) : "—"), cell(t.height_m ? t.height_m.toFixed(2) : "—"),
        cell(String(t.cameras.length)), cell(((state.time_ns - t.updated_ns) / 1e9).toFixed(1)),
      );
      return tr;
    });
    document.querySelector("#track-table tbody").replaceChildren(...rows);

    const order = { server: 0, head: 1, camera: 2, unknown: 3 };
    const nodes = [...state.nodes].sort((a, b) => order[a.role] - order[b.role] || a.id - b.id);
    const health = nodes.map((n) => {
      const h = n.health;
      const tr = Ocelli.el("tr");
      const life = !n.up ? ["down", "bad"] : n.stale ? ["stale", "warn"] : ["up", "up"];
      const sync = h.sync_error_ms === null || h.sync_error_ms === undefined ? "—" : h.sync_error_ms.toFixed(2);
      const rejected = h.rejected + h.rejected_by_server;
      tr.append(
        cell(n.role + " " + n.id), cell(life[0], life[1]), cell(n.role === "camera" ? (n.mode || "—") : ""),
        cell(n.head ? String(n.head) : ""), cell(sync, h.sync_error_ms > 5 ? "warn" : ""),
        cell(String(h.dropped), h.dropped ? "warn" : ""), cell(String(h.lost), h.lost ? "warn" : ""),
        cell(n.role === "head" ? String(h.late) : "", h.late ? "warn" : ""), cell(String(rejected), rejected ? "bad" : ""),
      );
      return tr;
    });
    document.querySelector("#health tbody").replaceChildren(...health);

    const recent = [...state.handovers].reverse().slice(0, 8).map((h) =>
      Ocelli.el("li", state.time - h.time < 3 ? { class: "fresh" } : {},
        Ocelli.fmtTime(h.time) + " · t" + h.global + ": " + (h.from ? "head " + h.from : "—") + " → head " + h.to + " (" + h.reason.replace("_", " ") + ")"));
    document.getElementById("handovers").replaceChildren(...(recent.length ? recent : [Ocelli.el("li", {}, "none yet")]));
  }

  function render(state) {
    latest = state;
    const key = JSON.stringify([state.world, state.nodes.map((n) => n.region), svg.clientWidth, svg.clientHeight]);
    if (key !== worldKey) {
      worldKey = key;
      view = fit(state.world);
      drawStatic(state);
    }
    drawCameras(state);
    drawTracks(state);
    flash(state);
    tables(state);
  }

  window.addEventListener("resize", () => { if (latest) render(latest); });
  Ocelli.connect(render);
})();
