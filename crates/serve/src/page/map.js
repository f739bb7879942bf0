// The live map: plan from /v1/plan, sessions from /v1/sessions, then live estimates from the
// Server-Sent Events of /v1/live read with fetch (the token travels in the Authorization
// header). Every server string is inserted with textContent or drawn with fillText.
"use strict";
(function () {
  const RECENT = 64;
  const canvas = document.getElementById("map");
  const ctx = canvas.getContext("2d");
  const list = document.getElementById("sessions");
  const status = document.getElementById("status");
  const counter = document.getElementById("event-count");
  const sessions = new Map(); // id -> {device, scheme, track: [est], closed, li}
  let plan = null;
  let events = 0;
  let token = "";
  const palette = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2"];

  function setStatus(text) { status.textContent = text; document.body.dataset.status = text; }

  function tokenFromFragment() {
    const m = /(?:^|[#&])token=([^&]*)/.exec(location.hash);
    return m ? decodeURIComponent(m[1]) : "";
  }

  async function api(path) {
    const r = await fetch(path, { headers: { Authorization: "Bearer " + token } });
    if (!r.ok) throw new Error(path + ": HTTP " + r.status);
    return r.json();
  }

  function colour(id) {
    let h = 0;
    for (const c of id) h = (h * 31 + c.charCodeAt(0)) >>> 0;
    return palette[h % palette.length];
  }

  function bounds() {
    if (plan && plan.plan) return { x0: 0, y0: 0, x1: plan.plan.width, y1: plan.plan.height };
    let b = null;
    for (const s of sessions.values()) for (const e of s.track) {
      if (!b) b = { x0: e.x, y0: e.y, x1: e.x, y1: e.y };
      b.x0 = Math.min(b.x0, e.x); b.y0 = Math.min(b.y0, e.y);
      b.x1 = Math.max(b.x1, e.x); b.y1 = Math.max(b.y1, e.y);
    }
    if (!b) return { x0: 0, y0: 0, x1: 100, y1: 100 };
    return { x0: b.x0 - 10, y0: b.y0 - 10, x1: b.x1 + 10, y1: b.y1 + 10 };
  }

  function draw() {
    const w = canvas.clientWidth || canvas.width, h = canvas.clientHeight || canvas.height;
    if (canvas.width !== w) canvas.width = w;
    if (canvas.height !== h) canvas.height = h;
    const b = bounds();
    const scale = Math.min((w - 20) / Math.max(b.x1 - b.x0, 1), (h - 20) / Math.max(b.y1 - b.y0, 1));
    const px = (x) => 10 + (x - b.x0) * scale;
    const py = (y) => h - 10 - (y - b.y0) * scale; // north up
    ctx.clearRect(0, 0, w, h);
    const ring = (pts) => {
      ctx.beginPath();
      pts.forEach((p, i) => (i ? ctx.lineTo(px(p[0]), py(p[1])) : ctx.moveTo(px(p[0]), py(p[1]))));
      ctx.closePath();
    };
    if (plan && plan.plan) {
      ctx.fillStyle = "#ffffff"; ctx.strokeStyle = "#555"; ctx.lineWidth = 1.5;
      for (const o of plan.plan.outline) { ring(o); ctx.fill(); ctx.stroke(); }
      ctx.fillStyle = "#eef1f5"; ctx.strokeStyle = "#99a"; ctx.lineWidth = 1;
      for (const u of plan.plan.units) { ring(u); ctx.fill(); ctx.stroke(); }
    }
    for (const [id, s] of sessions) {
      if (s.closed || s.track.length === 0) continue;
      const c = colour(id);
      ctx.strokeStyle = c; ctx.lineWidth = 2; ctx.globalAlpha = 0.6;
      ctx.beginPath();
      s.track.forEach((e, i) => (i ? ctx.lineTo(px(e.x), py(e.y)) : ctx.moveTo(px(e.x), py(e.y))));
      ctx.stroke();
      const e = s.track[s.track.length - 1];
      if (e.r95_m != null) {
        ctx.globalAlpha = 0.15; ctx.fillStyle = c;
        ctx.beginPath(); ctx.arc(px(e.x), py(e.y), Math.max(e.r95_m * scale, 2), 0, 2 * Math.PI); ctx.fill();
      }
      ctx.globalAlpha = 1; ctx.fillStyle = c;
      ctx.beginPath(); ctx.arc(px(e.x), py(e.y), 5, 0, 2 * Math.PI); ctx.fill();
      ctx.fillStyle = "#222"; ctx.font = "12px system-ui, sans-serif";
      ctx.fillText(s.device, px(e.x) + 8, py(e.y) - 8); // text, never markup
    }
  }

  let pending = false;
  function redraw() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => { pending = false; draw(); });
  }

  function fmt(v, d) { return v == null ? "-" : Number(v).toFixed(d); }

  function render(id) {
    const s = sessions.get(id);
    if (!s.li) {
      s.li = document.createElement("li");
      s.li.dataset.session = id;
      const sw = document.createElement("span"); sw.className = "swatch"; sw.style.background = colour(id);
      const dev = document.createElement("span"); dev.className = "device";
      const meta = document.createElement("div"); meta.className = "meta";
      s.li.append(sw, dev, meta);
      list.append(s.li);
    }
    const [, dev, meta] = s.li.children;
    dev.textContent = s.device;
    const e = s.track[s.track.length - 1];
    meta.textContent = s.scheme + " · " + (s.closed ? "closed" :
      e ? "x " + fmt(e.x, 1) + " m, y " + fmt(e.y, 1) + " m, floor " + (e.floor == null ? "?" : e.floor) +
          ", 95 % radius " + fmt(e.r95_m, 1) + " m, " + s.track.length + " recent" : "no estimate yet");
    s.li.dataset.estimates = String(s.track.length);
    s.li.dataset.state = s.closed ? "closed" : "open";
  }

  function upsert(id, device, scheme) {
    if (!sessions.has(id)) sessions.set(id, { device: String(device), scheme: String(scheme), track: [], closed: false, li: null });
    return sessions.get(id);
  }

  function onEvent(kind, data) {
    let ev;
    try { ev = JSON.parse(data); } catch (_) { return; }
    if (!ev || typeof ev.session !== "string") return;
    events += 1;
    counter.textContent = String(events);
    document.body.dataset.events = String(events);
    const s = upsert(ev.session, ev.device, ev.scheme);
    if (kind === "closed") {
      s.closed = true;
    } else if (kind === "estimate" && ev.estimate) {
      s.track.push({ ...ev.estimate, r95_m: ev.r95_m });
      if (s.track.length > RECENT) s.track.shift();
    }
    render(ev.session);
    redraw();
  }

  async function follow() {
    const r = await fetch("/v1/live", { headers: { Authorization: "Bearer " + token, Accept: "text/event-stream" } });
    if (!r.ok || !r.body) throw new Error("/v1/live: HTTP " + r.status);
    setStatus("live");
    const reader = r.body.getReader();
    const dec = new TextDecoder();
    let buf = "";
    for (;;) {
      const { value, done } = await reader.read();
      if (done) break;
      buf += dec.decode(value, { stream: true });
      let cut;
      while ((cut = buf.indexOf("\n\n")) >= 0) {
        const block = buf.slice(0, cut); buf = buf.slice(cut + 2);
        let kind = "message", data = "";
        for (const line of block.split("\n")) {
          if (line.startsWith("event:")) kind = line.slice(6).trim();
          else if (line.startsWith("data:")) data += line.slice(5).trim();
        }
        if (data) onEvent(kind, data);
      }
    }
    setStatus("stream ended");
  }

  async function start() {
    try {
      plan = await api("/v1/plan");
      document.getElementById("site").textContent = "wipdr live map: " + String(plan.name);
      const open = await api("/v1/sessions");
      for (const s of open.sessions) {
        const entry = upsert(s.id, s.device, s.scheme);
        entry.track = (s.recent || []).slice(-RECENT);
        render(s.id);
      }
      redraw();
      document.body.dataset.sessions = String(open.sessions.length);
      setStatus("loaded");
      await follow();
    } catch (e) {
      setStatus("error: " + e.message);
    }
  }

  window.addEventListener("resize", redraw);
  token = tokenFromFragment();
  if (token) {
    start();
  } else {
    const form = document.getElementById("login");
    form.hidden = false;
    setStatus("give a token");
    form.addEventListener("submit", (ev) => {
      ev.preventDefault();
      token = document.getElementById("token").value.trim();
      form.hidden = true;
      start();
    });
  }
})();
