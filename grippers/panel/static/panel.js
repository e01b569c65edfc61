// The grippers panel: one card per gripper, fed by the server's WebSocket (grippers/panel/app.py).
// Plain JavaScript, no library, no build step. Values on the wire are in mm, mm/s, N and A.
"use strict";

const WINDOW_S = 30; // the chart's time span
const cards = new Map(); // name -> card
let socket = null;
let pageId = null;
let nextId = 1;
const pending = new Map(); // request id -> card name

function fmt(value, digits, unit) {
  return value === null || value === undefined ? "not reported" : `${value.toFixed(digits)} ${unit}`;
}

function makeCard(snap) {
  const node = document.getElementById("card").content.firstElementChild.cloneNode(true);
  const name = snap.name;
  const key = `g${cards.size}`;
  node.setAttribute("aria-label", name);
  node.querySelector(".title").textContent = name;
  for (const label of node.querySelectorAll("label[data-for]")) {
    const id = `${key}-${label.dataset.for}`;
    label.htmlFor = id;
    node.querySelector(`output[data-name="${label.dataset.for}"]`).id = id;
  }
  const card = {
    name, node, snap, error: null, history: [],
    out: (n) => node.querySelector(`output[data-name="${n}"]`),
    input: (n) => node.querySelector(`input[data-arg="${n}"]`),
  };
  node.addEventListener("click", (event) => onClick(card, event));
  document.getElementById("cards").appendChild(node);
  cards.set(name, card);
  return card;
}

function number(card, arg) {
  const text = card.input(arg).value;
  return text === "" ? null : Number(text);
}

function onClick(card, event) {
  const button = event.target.closest("button");
  if (!button) return;
  let command = button.dataset.command;
  let args = {};
  const speed = number(card, "speed_mm_s");
  if (button.classList.contains("record")) {
    command = "record";
    args = { on: button.getAttribute("aria-pressed") !== "true" };
  } else if (button.dataset.jog) {
    command = "jog";
    args = { delta_mm: Number(button.dataset.jog), speed_mm_s: speed };
  } else if (command === "move") {
    args = { width_mm: number(card, "width_mm"), speed_mm_s: speed };
  } else if (command === "grasp") {
    args = { width_mm: number(card, "width_mm"), force_n: number(card, "force_n"), speed_mm_s: speed };
  } else if (command === "release") {
    args = { speed_mm_s: speed };
  }
  if (!command) return;
  send(card, command, args);
}

function send(card, command, args) {
  if (!socket || socket.readyState !== WebSocket.OPEN) {
    showError(card, { error: "ConnectionLost", message: `${command}: the panel's server is not reachable` });
    return;
  }
  const id = nextId++;
  pending.set(id, card.name);
  socket.send(JSON.stringify({ id, name: card.name, command, args }));
}

function showError(card, reply) {
  card.error = { kind: reply.error, text: reply.message };
  render(card);
}

function onReply(message) {
  const name = message.name || pending.get(message.id);
  pending.delete(message.id);
  const card = cards.get(name);
  if (!card) return;
  if (message.ok) {
    card.error = null;
    render(card);
  } else {
    showError(card, message);
  }
}

function alertText(card) {
  const snap = card.snap;
  if (!snap.connected) return snap.lost || "connection lost";
  const faults = (snap.state && snap.state.faults) || [];
  if (card.error) {
    // An error whose condition has ended is cleared: a fast stop acknowledged, a link back.
    const kind = card.error.kind;
    if (kind === "FastStopActive" && !faults.includes("fast_stop")) card.error = null;
    else if (kind === "ConnectionLost" && snap.connected) card.error = null;
    else return card.error.text;
  }
  if (faults.length) return `fault: ${faults.join(", ")}`;
  return "";
}

function render(card) {
  const snap = card.snap;
  const node = card.node;
  const info = snap.info;
  if (info) {
    const parts = [info.vendor, info.model, info.family && `family ${info.family}`,
      info.serial && `serial ${info.serial}`, info.firmware && `firmware ${info.firmware}`,
      info.profile && `profile ${info.profile}`, snap.url];
    node.querySelector(".identity").textContent = parts.filter(Boolean).join(" · ");
  }
  const connection = node.querySelector(".connection");
  connection.textContent = snap.connected ? "connected" : "connection lost";
  connection.classList.toggle("lost", !snap.connected);
  const controller = snap.controller;
  node.querySelector(".controller").textContent = controller === null ? "observing (nobody controls)"
    : controller.id === pageId ? "this page controls" : `${controller.label} controls`;
  const alert = node.querySelector(".alert");
  const text = alertText(card);
  if (alert.textContent !== text) alert.textContent = text;
  const st = snap.state;
  if (st) {
    card.out("width").textContent = fmt(st.width_mm, 1, "mm");
    card.out("speed").textContent = fmt(st.speed_mm_s, 1, "mm/s");
    card.out("force").textContent = st.force_n !== null ? fmt(st.force_n, 1, "N")
      : st.current_a !== null ? fmt(st.current_a, 2, "A") : "not reported";
    const flags = [st.grasp_state];
    if (st.moving) flags.push("moving");
    if (!st.referenced) flags.push("not referenced");
    card.out("state").textContent = flags.join(", ");
    card.out("faults").textContent = st.faults.length ? st.faults.join(", ") : "none";
  }
  const hot = snap.temperature_c;
  node.querySelector(".temperature").hidden = hot === null || hot === undefined;
  if (!node.querySelector(".temperature").hidden) card.out("temperature").textContent = fmt(hot, 1, "°C");
  const limits = snap.limits;
  if (limits) {
    bound(card.input("width_mm"), limits.min_width_mm, limits.max_width_mm);
    bound(card.input("force_n"), limits.min_force_n, limits.max_force_n);
    bound(card.input("speed_mm_s"), limits.min_speed_mm_s, limits.max_speed_mm_s);
  }
  const record = node.querySelector("button.record");
  record.setAttribute("aria-pressed", snap.recording ? "true" : "false");
  for (const kind of ["csv", "mcap"]) {
    const link = node.querySelector(`a.${kind}`);
    const file = snap.downloads && snap.downloads[kind];
    link.hidden = !file;
    if (file) {
      link.href = `api/grippers/${encodeURIComponent(snap.name)}/recording.${kind}`;
      link.setAttribute("download", file);
    }
  }
}

function bound(input, lo, hi) {
  if (lo !== null && lo !== undefined) input.min = String(lo);
  if (hi !== null && hi !== undefined) input.max = String(hi);
}

function onUpdate(snaps) {
  for (const snap of snaps) {
    const card = cards.get(snap.name) || makeCard(snap);
    card.snap = { ...card.snap, ...snap }; // the identity and limits come only when they change
    const st = snap.state;
    if (st && (!card.history.length || card.history[card.history.length - 1].t !== st.t)) {
      const force = st.force_n !== null ? st.force_n : st.current_a;
      card.history.push({ t: st.t, w: st.width_mm, f: force, current: st.force_n === null });
      const oldest = st.t - WINDOW_S;
      while (card.history.length && card.history[0].t < oldest) card.history.shift();
    }
    render(card);
  }
}

// -- the chart: width and force (or current) over the last 30 s, drawn on a canvas --------------------

function drawChart(card) {
  const canvas = card.node.querySelector("canvas");
  const ctx = canvas.getContext("2d");
  const w = canvas.width;
  const h = canvas.height;
  ctx.clearRect(0, 0, w, h);
  ctx.strokeStyle = "#e5e7eb";
  ctx.lineWidth = 1;
  for (let i = 1; i < 4; i++) {
    ctx.beginPath();
    ctx.moveTo(0, (h * i) / 4);
    ctx.lineTo(w, (h * i) / 4);
    ctx.stroke();
  }
  const points = card.history;
  if (points.length < 2) return;
  const limits = card.snap.limits || {};
  const now = points[points.length - 1].t;
  const x = (t) => w - ((now - t) / WINDOW_S) * w;
  const current = points[points.length - 1].current;
  const series = [
    ["w", "#2563eb", limits.max_width_mm || Math.max(...points.map((p) => p.w || 0), 1)],
    ["f", "#d97706", (current ? limits.max_current_a : limits.max_force_n) || Math.max(...points.map((p) => p.f || 0), 1)],
  ];
  card.node.querySelector(".legend .f").textContent = current ? "current (A)" : "force (N)";
  for (const [key, color, top] of series) {
    ctx.strokeStyle = color;
    ctx.lineWidth = 2;
    ctx.beginPath();
    let started = false;
    for (const p of points) {
      if (p[key] === null || p[key] === undefined) { started = false; continue; }
      const y = h - 4 - (Math.max(0, p[key]) / top) * (h - 8);
      if (started) ctx.lineTo(x(p.t), y); else ctx.moveTo(x(p.t), y);
      started = true;
    }
    ctx.stroke();
  }
}

function drawAll() {
  for (const card of cards.values()) drawChart(card);
}

// -- the connection -------------------------------------------------------------------------------

function connect() {
  const url = new URL("ws", window.location.href);
  url.protocol = url.protocol === "https:" ? "wss:" : "ws:";
  url.search = "";
  const link = document.getElementById("link");
  socket = new WebSocket(url);
  socket.addEventListener("open", () => { link.textContent = "connected to the panel"; });
  socket.addEventListener("message", (event) => {
    const message = JSON.parse(event.data);
    if (message.type === "hello") {
      pageId = message.page;
      link.textContent = `connected as ${message.label}`;
    } else if (message.type === "update") {
      onUpdate(message.grippers);
    } else if (message.type === "reply") {
      onReply(message);
    } else if (message.type === "done" && !message.ok) {
      const card = cards.get(message.name);
      if (card) showError(card, message);
    }
  });
  socket.addEventListener("close", () => {
    link.textContent = "disconnected from the panel; retrying";
    for (const card of cards.values()) {
      card.snap = { ...card.snap, connected: false, lost: "the panel's server is not reachable" };
      render(card);
    }
    window.setTimeout(connect, 1000);
  });
}

connect();
window.setInterval(drawAll, 100);
