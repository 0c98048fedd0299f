// Ocelli 3D view, drawn with Canvas 2D and a perspective projection written here (no WebGL, so
// it also draws in browsers without a GPU): the room and its walls, head regions on the floor,
// each camera as its frustum coloured by mode, each person as an upright box of its height with
// its id, its 2σ ellipse and trail on the floor. Drag to orbit, wheel to zoom.
"use strict";

(() => {
  const canvas = document.getElementById("view3d");
  const labels = document.getElementById("labels");
  const ctx = canvas.getContext("2d");
  const orbit = { yaw: -2.2, pitch: 0.62, dist: 0 };
  let latest = null;
  const BOX = 0.45; // width and depth of a person's box, m
  const UNKNOWN_HEIGHT = 1.7;

  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const norm = (a) => { const l = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / l, a[1] / l, a[2] / l]; };

  // The eye orbits the room's centre; world z is up.
  function camera(state) {
    const lo = state.world.min, hi = state.world.max;
    const target = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, 0.5];
    const span = Math.hypot(hi[0] - lo[0], hi[1] - lo[1]);
    if (!orbit.dist) orbit.dist = span * 1.05;
    const cp = Math.cos(orbit.pitch);
    const eye = [target[0] + orbit.dist * cp * Math.cos(orbit.yaw), target[1] + orbit.dist * cp * Math.sin(orbit.yaw), target[2] + orbit.dist * Math.sin(orbit.pitch)];
    const f = norm(sub(target, eye));
    const r = norm(cross(f, [0, 0, 1]));
    const u = cross(r, f);
    const w = canvas.width, h = canvas.height;
    const focal = (0.5 * Math.min(w, h)) / Math.tan(0.45);
    return {
      // World point → [screen x, screen y, depth]; null behind the eye.
      project(p) {
        const d = sub(p, eye);
        const z = dot(d, f);
        if (z < 0.05) return null;
        return [w / 2 + (focal * dot(d, r)) / z, h / 2 - (focal * dot(d, u)) / z, z];
      },
    };
  }

  function path(cam, pts, close) {
    const q = pts.map((p) => cam.project(p));
    if (q.some((p) => !p)) return false;
    ctx.beginPath();
    q.forEach((p, i) => (i ? ctx.lineTo(p[0], p[1]) : ctx.moveTo(p[0], p[1])));
    if (close) ctx.closePath();
    return true;
  }

  function line(cam, pts, colour, width, dash) {
    if (!path(cam, pts, false)) return;
    ctx.strokeStyle = colour;
    ctx.lineWidth = width;
    ctx.setLineDash(dash || []);
    ctx.stroke();
    ctx.setLineDash([]);
  }

  function modeColour(n) {
    if (!n.up) return "#e02020";
    return Ocelli.MODE_COLOURS[n.mode] || "#667";
  }

  // Faces of a person's box (sides and top), each [corners, fill].
  function boxFaces(t, colour) {
    const [x, y] = t.position, h = t.height_m || UNKNOWN_HEIGHT, a = BOX / 2;
    const c = [[x - a, y - a], [x + a, y - a], [x + a, y + a], [x - a, y + a]];
    const faces = [];
    for (let i = 0; i < 4; i++) {
      const p = c[i], q = c[(i + 1) % 4];
      faces.push([[[p[0], p[1], 0], [q[0], q[1], 0], [q[0], q[1], h], [p[0], p[1], h]], colour, i % 2 ? 0.78 : 0.62]);
    }
    faces.push([c.map((p) => [p[0], p[1], h]), colour, 0.95]);
    return faces;
  }

  function draw() {
    const state = latest;
    if (!state) return;
    const dpr = window.devicePixelRatio || 1;
    const cw = canvas.clientWidth || 800, ch = canvas.clientHeight || 600;
    if (canvas.width !== Math.round(cw * dpr) || canvas.height !== Math.round(ch * dpr)) {
      canvas.width = Math.round(cw * dpr);
      canvas.height = Math.round(ch * dpr);
    }
    const cam = camera(state);
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = "#10141b";
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    const lo = state.world.min, hi = state.world.max;

    // Floor: fill, 1 m grid, head regions.
    if (path(cam, [[lo[0], lo[1], 0], [hi[0], lo[1], 0], [hi[0], hi[1], 0], [lo[0], hi[1], 0]], true)) {
      ctx.fillStyle = "#182030";
      ctx.fill();
    }
    for (let x = Math.ceil(lo[0]); x <= hi[0]; x++) line(cam, [[x, lo[1], 0], [x, hi[1], 0]], "#253042", 1);
    for (let y = Math.ceil(lo[1]); y <= hi[1]; y++) line(cam, [[lo[0], y, 0], [hi[0], y, 0]], "#253042", 1);
    for (const n of state.nodes) {
      if (n.role !== "head" || !n.region) continue;
      const [a, b, c, d] = n.region, e = 0.05;
      line(cam, [[a + e, b + e, 0], [c - e, b + e, 0], [c - e, d - e, 0], [a + e, d - e, 0], [a + e, b + e, 0]], Ocelli.headColour(state, n.id), 2, [8, 6]);
    }
    // Room edges.
    const top = hi[2];
    const corners = [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]];
    for (let i = 0; i < 4; i++) {
      const p = corners[i], q = corners[(i + 1) % 4];
      line(cam, [[p[0], p[1], 0], [q[0], q[1], 0]], "#5b6a80", 2);
      line(cam, [[p[0], p[1], top], [q[0], q[1], top]], "#3a4556", 1);
      line(cam, [[p[0], p[1], 0], [p[0], p[1], top]], "#3a4556", 1);
    }
    // Trails and ellipses on the floor.
    for (const t of state.tracks) {
      if (!t.updated_ns) continue;
      const colour = Ocelli.headColour(state, t.owner);
      if (t.trail.length > 1) line(cam, t.trail.map((p) => [p[1], p[2], 0.01]), colour, 2.5);
      if (t.ellipse) {
        const e = t.ellipse, ring = [];
        for (let i = 0; i <= 32; i++) {
          const a = (i / 32) * 2 * Math.PI, u = e.semi_major * Math.cos(a), v = e.semi_minor * Math.sin(a);
          ring.push([t.position[0] + u * Math.cos(e.angle) - v * Math.sin(e.angle), t.position[1] + u * Math.sin(e.angle) + v * Math.cos(e.angle), 0.01]);
        }
        line(cam, ring, colour, 1.5);
      }
    }
    // Walls and people: filled faces, far ones first.
    const faces = [];
    for (const wall of state.world.walls) {
      faces.push([[[wall.from[0], wall.from[1], 0], [wall.to[0], wall.to[1], 0], [wall.to[0], wall.to[1], wall.height], [wall.from[0], wall.from[1], wall.height]], "#9aa6ba", 0.55]);
    }
    for (const t of state.tracks) {
      if (t.updated_ns) faces.push(...boxFaces(t, Ocelli.headColour(state, t.owner)));
    }
    const depth = (pts) => pts.reduce((s, p) => { const q = cam.project(p); return s + (q ? q[2] : 1e9); }, 0) / pts.length;
    faces.sort((a, b) => depth(b[0]) - depth(a[0]));
    for (const [pts, colour, alpha] of faces) {
      if (!path(cam, pts, true)) continue;
      ctx.globalAlpha = alpha;
      ctx.fillStyle = colour;
      ctx.fill();
      ctx.globalAlpha = 1;
      ctx.strokeStyle = "rgba(10,12,16,0.8)";
      ctx.lineWidth = 1;
      ctx.stroke();
    }
    // Cameras: frusta to where their view leaves the room, coloured by mode; the ones whose
    // measurements went into a track drawn strongly, the others faintly.
    const seeing = new Set(state.tracks.flatMap((t) => t.cameras));
    for (const n of state.nodes) {
      if (!n.camera) continue;
      const c = n.camera, colour = modeColour(n), dash = n.up && !n.stale ? [] : [4, 4];
      const strong = seeing.has(n.id) || !n.up;
      ctx.globalAlpha = strong ? 0.95 : 0.28;
      for (let i = 0; i < 4; i++) {
        line(cam, [c.position, c.frustum[i]], colour, strong ? 1.6 : 0.8, dash);
        line(cam, [c.frustum[i], c.frustum[(i + 1) % 4]], colour, strong ? 1.2 : 0.8, dash);
      }
      ctx.globalAlpha = 1;
      const p = cam.project(c.position);
      if (p) {
        ctx.fillStyle = colour;
        ctx.beginPath();
        ctx.arc(p[0], p[1], 4 * dpr, 0, 2 * Math.PI);
        ctx.fill();
      }
    }
    // Ids over the people, as page text.
    const tags = [];
    for (const t of state.tracks) {
      if (!t.updated_ns) continue;
      const p = cam.project([t.position[0], t.position[1], (t.height_m || UNKNOWN_HEIGHT) + 0.15]);
      if (!p) continue;
      const tag = Ocelli.el("div", { class: "label3d", "data-global": t.global }, "t" + t.global);
      tag.style.left = p[0] / dpr + "px";
      tag.style.top = p[1] / dpr + "px";
      tags.push(tag);
    }
    labels.replaceChildren(...tags);
  }

  function tables(state) {
    const rows = state.tracks.filter((t) => t.updated_ns).map((t) => {
      const tr = Ocelli.el("tr", { "data-global": t.global });
      for (const v of ["t" + t.global, String(t.owner), t.position[0].toFixed(2), t.position[1].toFixed(2), t.height_m ? t.height_m.toFixed(2) : "—"]) {
        tr.appendChild(Ocelli.el("td", {}, v));
      }
      return tr;
    });
    document.querySelector("#track-table tbody").replaceChildren(...rows);
  }

  let dragging = null;
  canvas.addEventListener("mousedown", (e) => { dragging = [e.clientX, e.clientY]; });
  window.addEventListener("mouseup", () => { dragging = null; });
  window.addEventListener("mousemove", (e) => {
    if (!dragging) return;
    orbit.yaw -= (e.clientX - dragging[0]) * 0.008;
    orbit.pitch = Math.min(1.5, Math.max(0.05, orbit.pitch + (e.clientY - dragging[1]) * 0.006));
    dragging = [e.clientX, e.clientY];
    draw();
  });
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    orbit.dist = Math.min(200, Math.max(2, orbit.dist * Math.exp(e.deltaY * 0.001)));
    draw();
  }, { passive: false });
  window.addEventListener("resize", draw);

  Ocelli.connect((state) => {
    latest = state;
    draw();
    tables(state);
  });
})();
