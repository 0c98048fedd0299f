// Ocelli viewer: what the map and the 3D view share — the connection to the viewer (a first
// snapshot from /api/state, then server-sent events from /events), the playback bar, and small
// formatting helpers. No libraries: the viewer must work offline.
"use strict";

const Ocelli = (() => {
  const HEAD_COLOURS = ["#4da3ff", "#c77dff", "#33d1c4", "#ffd23f", "#ff7eb6", "#9be564"];
  const MODE_COLOURS = { Active: "#3cb43c", CameraOff: "#ffa500", Inactive: "#909090" };

  function headColour(state, head) {
    const heads = state.nodes.filter((n) => n.role === "head").map((n) => n.id);
    const i = heads.indexOf(head);
    return HEAD_COLOURS[(i < 0 ? head : i) % HEAD_COLOURS.length];
  }

  // "Active" → "active", "CameraOff" → "camera_off"; a node that is down is "down".
  function modeClass(n) {
    if (!n.up) return "down";
    if (!n.mode) return "unknown";
    return n.mode === "CameraOff" ? "camera_off" : n.mode.toLowerCase();
  }

  // Cluster time: nanoseconds since the Unix epoch for a launched cluster, since the start for
  // a simulation.
  function fmtTime(seconds) {
    if (seconds > 1e9) {
      return new Date(seconds * 1000).toISOString().replace("T", " ").slice(0, 23) + " UTC";
    }
    return "t = " + seconds.toFixed(1) + " s";
  }

  function fmtDuration(s) {
    const m = Math.floor(s / 60);
    const sec = s - 60 * m;
    return m + ":" + sec.toFixed(1).padStart(4, "0");
  }

  function el(tag, attrs, text) {
    const e = document.createElement(tag);
    for (const k in attrs || {}) e.setAttribute(k, attrs[k]);
    if (text !== undefined) e.textContent = text;
    return e;
  }

  function post(path) {
    return fetch(path, { method: "POST" }).then((r) => {
      if (!r.ok) r.text().then((t) => console.warn("playback:", t));
    });
  }

  // The playback bar (only for recordings: the state carries `playback`).
  function playbackBar(state) {
    const bar = document.getElementById("playback");
    const p = state.playback;
    if (!bar) return;
    if (!p) { bar.classList.remove("on"); return; }
    bar.classList.add("on");
    const slider = document.getElementById("slider");
    const button = document.getElementById("playpause");
    const label = document.getElementById("playpos");
    const span = Math.max(0, p.end - p.start);
    slider.max = span.toFixed(2);
    if (!slider.dataset.dragging) slider.value = (p.position - p.start).toFixed(2);
    button.textContent = p.playing ? "Pause" : "Play";
    label.textContent = fmtDuration(Math.max(0, p.position - p.start)) + " / " + fmtDuration(span);
    if (!bar.dataset.wired) {
      bar.dataset.wired = "1";
      button.addEventListener("click", () => post("/api/playback/" + (button.textContent === "Play" ? "play" : "pause")));
      slider.addEventListener("input", () => { slider.dataset.dragging = "1"; });
      slider.addEventListener("change", () => {
        delete slider.dataset.dragging;
        post("/api/playback/seek?t=" + encodeURIComponent(slider.value));
      });
      document.getElementById("speed").addEventListener("change", (e) => post("/api/playback/speed?x=" + e.target.value));
    }
  }

  function problems(state) {
    const box = document.getElementById("problems");
    if (!box) return;
    const list = box.querySelector("ul");
    list.replaceChildren(...state.problems.map((p) => el("li", {}, p.text + (p.count > 1 ? " (×" + p.count + ")" : ""))));
    box.classList.toggle("on", state.problems.length > 0);
  }

  function header(state) {
    document.getElementById("clock").textContent =
      (state.scenario ? state.scenario + " · " : "") + fmtTime(state.time) + " · update " + state.seq;
    playbackBar(state);
    problems(state);
  }

  // Show the first snapshot, then every pushed state. `render(state)` draws one.
  function connect(render) {
    const conn = document.getElementById("conn");
    let seq = -1;
    const show = (state) => {
      if (state.seq < seq && !state.playback) return;
      seq = state.seq;
      if (state.playback && conn.className === "live") conn.textContent = "recording";
      header(state);
      render(state);
    };
    fetch("/api/state").then((r) => r.json()).then(show).catch((e) => console.warn("snapshot:", e));
    if (!window.EventSource) return;
    const events = new EventSource("/events");
    events.addEventListener("state", (e) => {
      const state = JSON.parse(e.data);
      conn.textContent = state.playback ? "recording" : "live";
      conn.className = "live";
      show(state);
    });
    events.onopen = () => { conn.textContent = "connected"; conn.className = "live"; };
    events.onerror = () => { conn.textContent = "reconnecting"; conn.className = "lost"; };
  }

  return { connect, headColour, modeClass, fmtTime, el, MODE_COLOURS };
})();
