// expertise-irl live page: draws the map and the estimate, sends moves over the WebSocket.
// The page sends only {type: "move", action}, {type: "mode", mode} and {type: "sync"}.
"use strict";
(function () {
  const KEYS = {
    ArrowUp: "up", ArrowDown: "down", ArrowLeft: "left", ArrowRight: "right",
    w: "up", s: "down", a: "left", d: "right", W: "up", S: "down", A: "left", D: "right",
  };
  const GROUPS = ["high", "medium", "low"];
  let info = null;   // the init message: map, colours, feature names
  let state = null;  // the last state message
  let ws = null;

  const $ = (id) => document.getElementById(id);

  function send(doc) {
    if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(doc));
  }

  function showMessage(text, kind) {
    const el = $("message");
    el.textContent = text || "";
    el.className = "message" + (text ? " " + kind : "");
  }

  function connect() {
    const proto = location.protocol === "https:" ? "wss://" : "ws://";
    ws = new WebSocket(proto + location.host + "/ws");
    ws.onmessage = (ev) => {
      const msg = JSON.parse(ev.data);
      if (msg.type === "init") {
        info = msg;
        render(msg.state);
      } else if (msg.type === "state") {
        render(msg);
        if (msg.message) showMessage(msg.message, "info");
        else if (msg.event === "moved") showMessage("", "");
      } else if (msg.type === "refused") {
        showMessage(msg.message, "refused");
      } else if (msg.type === "error") {
        showMessage("Error: " + msg.message, "refused");
      }
    };
    ws.onclose = () => { $("status").textContent = "disconnected — is the server still running? Reload to reconnect."; };
  }

  // ---------------------------------------------------------------- map
  const CELL_MAX = 56, CELL_MIN = 8, CELL_COMFORT = 16;  // px
  const PANEL_WANT = 420, PANEL_MIN = 280;  // px: the estimate panel beside the map

  // The cell size that lets the map fill the window: beside the estimate panel (narrowed down to
  // PANEL_MIN when that gives a large map comfortable cells) and above the controls. Where even
  // that leaves cells under CELL_MIN, the map takes the whole width and the panel goes below it.
  function cellSize() {
    const m = info.map, main = document.querySelector("main"), style = getComputedStyle(main);
    const map = $("map").getBoundingClientRect(), left = document.querySelector(".left");
    const width = main.clientWidth - parseFloat(style.paddingLeft) - parseFloat(style.paddingRight) - 2;
    const below = left.getBoundingClientRect().bottom - map.bottom + parseFloat(style.paddingBottom);
    const height = window.innerHeight - (map.top + window.scrollY) - below - 2;
    const gap = parseFloat(style.columnGap) || 0;
    const fit = (panel) => Math.floor(Math.min((width - panel - gap) / m.width, height / m.height, CELL_MAX));
    let cs = fit(PANEL_WANT);
    if (cs < CELL_COMFORT) cs = Math.max(cs, fit(PANEL_MIN));
    if (cs < CELL_MIN) cs = Math.floor(Math.min(width / m.width, CELL_MAX));
    return Math.max(CELL_MIN, cs);
  }

  function drawMap() {
    const m = info.map, c = info.colors, cs = cellSize();
    const canvas = $("map"), dpr = window.devicePixelRatio || 1;
    const W = m.width * cs, H = m.height * cs;
    if (canvas.width !== Math.round(W * dpr) || canvas.height !== Math.round(H * dpr)) {
      canvas.width = Math.round(W * dpr); canvas.height = Math.round(H * dpr);
      canvas.style.width = W + "px"; canvas.style.height = H + "px";
      document.querySelector(".left").style.width = Math.max(W + 2, 360) + "px";
    }
    canvas.dataset.cell = String(cs);
    const g = canvas.getContext("2d");
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    const arrows = { ">": [1, 0], "<": [-1, 0], "^": [0, -1], "v": [0, 1] };
    for (let y = 0; y < m.height; y++) {
      for (let x = 0; x < m.width; x++) {
        const ch = m.rows[y][x];
        g.fillStyle = c.zones[ch] || "#fafafa";
        g.fillRect(x * cs, y * cs, cs, cs);
      }
    }
    g.strokeStyle = c.grid; g.lineWidth = 0.6;
    g.beginPath();
    for (let x = 0; x <= m.width; x++) { g.moveTo(x * cs + 0.5, 0); g.lineTo(x * cs + 0.5, H); }
    for (let y = 0; y <= m.height; y++) { g.moveTo(0, y * cs + 0.5); g.lineTo(W, y * cs + 0.5); }
    g.stroke();
    for (let y = 0; y < m.height; y++) {
      for (let x = 0; x < m.width; x++) {
        const ch = m.rows[y][x], cx = (x + 0.5) * cs, cy = (y + 0.5) * cs;
        if (arrows[ch]) {
          const [dx, dy] = arrows[ch], r = cs * 0.28;
          g.fillStyle = c.arrow; g.beginPath();
          g.moveTo(cx + dx * r, cy + dy * r);
          g.lineTo(cx - dx * r - dy * r * 0.8, cy - dy * r + dx * r * 0.8);
          g.lineTo(cx - dx * r + dy * r * 0.8, cy - dy * r - dx * r * 0.8);
          g.closePath(); g.fill();
        } else if (ch === "G") {
          g.fillStyle = c.goal; g.beginPath(); g.arc(cx, cy, cs * 0.32, 0, 2 * Math.PI); g.fill();
        } else if (ch === "S") {
          g.strokeStyle = "#6b6b6b"; g.lineWidth = 1;
          g.strokeRect(cx - cs * 0.27, cy - cs * 0.27, cs * 0.54, cs * 0.54);
        }
      }
    }
    if (!state) return;
    const path = state.path;
    const px = (p) => (p[0] + 0.5) * cs, py = (p) => (p[1] + 0.5) * cs;
    if (path.length > 0) {  // the start of this episode
      g.strokeStyle = c.path; g.lineWidth = 2;
      g.strokeRect(px(path[0]) - cs * 0.36, py(path[0]) - cs * 0.36, cs * 0.72, cs * 0.72);
    }
    if (path.length > 1) {
      g.strokeStyle = c.path; g.lineWidth = Math.max(2, cs * 0.12); g.lineJoin = "round"; g.lineCap = "round";
      g.beginPath(); g.moveTo(px(path[0]), py(path[0]));
      for (const p of path.slice(1)) g.lineTo(px(p), py(p));
      g.stroke();
    }
    const a = state.position;
    g.fillStyle = c.agent; g.strokeStyle = "#fff"; g.lineWidth = 2;
    g.beginPath(); g.arc(px(a), py(a), cs * 0.34, 0, 2 * Math.PI); g.fill(); g.stroke();
    if (state.heading) {  // a heading world: a white bar along the current axis
      const r = cs * 0.22, hz = state.heading === "h";
      g.strokeStyle = "#fff"; g.lineWidth = Math.max(2, cs * 0.09); g.lineCap = "round";
      g.beginPath(); g.moveTo(px(a) - (hz ? r : 0), py(a) - (hz ? 0 : r));
      g.lineTo(px(a) + (hz ? r : 0), py(a) + (hz ? 0 : r)); g.stroke();
    }
  }

  // --------------------------------------------------------------- panels
  function bars(el, rows, cls) {
    el.replaceChildren();
    for (const [label, p, extra] of rows) {
      const l = document.createElement("div"); l.className = "label"; l.textContent = label;
      const t = document.createElement("div"); t.className = "track";
      const f = document.createElement("div"); f.className = "fill " + (extra || cls || "");
      f.style.width = (100 * Math.max(0, Math.min(1, p))).toFixed(1) + "%"; t.appendChild(f);
      const v = document.createElement("div"); v.className = "value";
      v.textContent = (100 * p).toFixed(p < 0.001 && p > 0 ? 2 : 1) + "%";
      el.append(l, t, v);
    }
  }

  function fmtBeta(b) { return String(+b.toPrecision(3)); }

  function drawHistory() {
    const canvas = $("history"), dpr = window.devicePixelRatio || 1;
    const W = Math.max(200, Math.min(440, canvas.parentElement.clientWidth - 24)), H = 170;  // the card's width
    if (canvas.width !== W * dpr) {
      canvas.width = W * dpr; canvas.height = H * dpr; canvas.style.width = W + "px"; canvas.style.height = H + "px";
    }
    const g = canvas.getContext("2d");
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.clearRect(0, 0, W, H);
    const L = 44, R = 36, T = 8, B = 22, w = W - L - R, h = H - T - B;
    const est = state.estimate, hist = state.history;
    // An adaptive set changes between episodes: the axes span the current set and every value shown.
    const bv = est.beta_values, seen = bv.concat(hist.beta_hat);
    const lo = Math.log(Math.min(...seen)), hi = Math.log(Math.max(...seen));
    const emax = Math.max(Math.log(nHypotheses()), ...hist.entropy) || 1;
    const n = hist.beta_hat.length;
    const X = (i) => L + (n <= 1 ? w * i : (w * i) / n);
    const Yb = (b) => T + h - (h * (Math.log(b) - lo)) / ((hi - lo) || 1);
    const Ye = (e) => T + h - (h * e) / emax;
    g.strokeStyle = "#cfd4da"; g.lineWidth = 1; g.strokeRect(L, T, w, h);
    g.fillStyle = "#66717d"; g.font = "10px system-ui, sans-serif"; g.textAlign = "right"; g.textBaseline = "middle";
    const every = Math.ceil(bv.length / 8);  // at most 8 labelled values
    for (const b of bv.filter((_, i) => i % every === 0)) {
      g.fillText(fmtBeta(b), L - 4, Yb(b));
      g.strokeStyle = "#eef0f3"; g.beginPath(); g.moveTo(L, Yb(b)); g.lineTo(L + w, Yb(b)); g.stroke();
    }
    g.textAlign = "left";
    g.fillText("0", L + w + 4, Ye(0)); g.fillText(emax.toFixed(1), L + w + 4, Ye(emax));
    g.textAlign = "center"; g.textBaseline = "top";
    g.fillText("actions: " + n, L + w / 2, T + h + 6);
    g.setLineDash([3, 3]); g.strokeStyle = "#999";
    for (const i of hist.episode_starts) {
      if (i > 0 && i < n) { g.beginPath(); g.moveTo(X(i), T); g.lineTo(X(i), T + h); g.stroke(); }
    }
    g.setLineDash([]);
    const line = (vals, Y, colour) => {  // value k is the estimate after action k + 1
      g.strokeStyle = colour; g.lineWidth = 1.8; g.beginPath();
      vals.forEach((v, k) => { if (k === 0) g.moveTo(X(k + 1), Y(v)); else g.lineTo(X(k + 1), Y(v)); });
      g.stroke();
      if (vals.length === 1) { g.fillStyle = colour; g.fillRect(X(1) - 2, Y(vals[0]) - 2, 4, 4); }
    };
    if (n > 0) {
      line(hist.beta_hat, Yb, "#0b2e59");
      line(hist.entropy, Ye, "#d9480f");
    }
  }

  // The size of the set the estimate is over (an adaptive set is refined after each episode).
  function nHypotheses() {
    return (state && state.n_hypotheses) || info.n_hypotheses;
  }

  function render(s) {
    state = s;
    const est = s.estimate;
    $("beta-hat").textContent = est.beta_hat.toPrecision(4);
    const now = s.expertise_now;
    $("beta-now-line").hidden = s.expertise_now === undefined;
    $("beta-now").textContent = now ? now.beta_mean.toPrecision(3) + " (90%: " + fmtBeta(now.q05) + "–" +
      fmtBeta(now.q95) + ", episode " + now.episode + ")" : "–";
    const teach = s.teaching;  // --model pedagogical: teaching or doing, from every action so far
    $("teaching-line").hidden = teach === undefined;
    $("teaching").textContent = teach ? teach.reading + "; λ̂ = " + fmtBeta(teach.lambda_hat) + " (90%: " +
      fmtBeta(teach.lambda_interval[0]) + "–" + fmtBeta(teach.lambda_interval[1]) + ")" : "–";
    $("teaching").dataset.verdict = teach ? teach.verdict : "";
    $("group").textContent = est.expertise_group + " expertise";
    $("entropy").textContent = "posterior entropy " + est.entropy.toFixed(3) + " nats of " +
      Math.log(nHypotheses()).toFixed(2) + " (" + nHypotheses() + " hypotheses)";
    bars($("beta-bars"), est.beta_values.map((b, i) => ["β = " + fmtBeta(b), est.beta_probabilities[i]]));
    bars($("group-bars"), GROUPS.map((k) => [k, est.group_probabilities[k], "group-" + k]));
    bars($("theta-bars"), info.feature_names.map((f, i) => [f, est.theta_hat[i]]), "theta");
    $("status").innerHTML = "";
    const parts = [
      ["map", info.map.name.split(/[\\/]/).pop()], ["episode", s.episode], ["step", s.step],
      ["at", "(" + s.position[0] + ", " + s.position[1] + ")"],
      ["actions recorded", s.actions], ["episodes done", s.episodes_done],
    ];
    if (s.heading) parts.splice(4, 0, ["heading", s.heading === "h" ? "horizontal" : "vertical"]);
    for (const [k, v] of parts) {
      const span = document.createElement("span");
      span.id = { map: "map-name", "actions recorded": "actions", "episodes done": "episodes-done",
                  at: "position" }[k] || k;
      span.dataset.value = String(v);
      span.textContent = k + " " + v;
      if (k === "episode") span.title = "numbered from 0, as in the episode column of demos.csv";
      $("status").appendChild(span);
    }
    $("active").checked = s.mode === "active";
    for (const dot of document.querySelectorAll(".goal-dot")) dot.style.background = info.colors.goal;
    $("start").textContent = s.start ? s.start.why : "";
    drawMap();
    drawHistory();
  }

  // --------------------------------------------------------------- input
  document.addEventListener("keydown", (ev) => {
    if (ev.ctrlKey || ev.metaKey || ev.altKey) return;
    const action = KEYS[ev.key];
    if (!action) return;
    ev.preventDefault();
    if (state && state.event === "refining") return;  // the next start is chosen after the refinement
    send({ type: "move", action: action });
  });
  document.addEventListener("DOMContentLoaded", () => {
    for (const b of document.querySelectorAll(".pad button")) {
      b.addEventListener("click", () => {
        if (!(state && state.event === "refining")) send({ type: "move", action: b.dataset.action });
      });
    }
    $("active").addEventListener("change", (ev) => send({ type: "mode", mode: ev.target.checked ? "active" : "random" }));
    connect();
  });
  let resizing = false;
  window.addEventListener("resize", () => {  // the map follows the window's size
    if (resizing || !info) return;
    resizing = true;
    requestAnimationFrame(() => { resizing = false; drawMap(); drawHistory(); });
  });
})();
