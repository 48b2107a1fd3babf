// The panel's page: one WebSocket to the panel's server (manus_stack/panel/server.py says
// what travels on it), the task buttons and the pad built from its "hello", and every
// "view" shown as it comes. A page that hears nothing for SILENT_MS says it has no
// connection, stops its pad and connects again.

import { Hold } from "./hold.js";
import { Scanner } from "./scan.js";

const SILENT_MS = 2500; // the server sends a view at least every second
const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);

let ws = null;
let heard = 0;
let built = false;
let view = null;
let hold = null;
let scanner = null;

function send(msg) {
  if (!ws || ws.readyState !== WebSocket.OPEN) return false;
  ws.send(JSON.stringify(msg));
  return true;
}

function connect() {
  ws = new WebSocket(`ws://${location.host}/ws`);
  ws.onmessage = (e) => {
    heard = Date.now();
    const msg = JSON.parse(e.data);
    if (msg.t === "hello") setUp(msg);
    else if (msg.t === "view") show(msg);
  };
  ws.onclose = () => {
    ws = null;
    offline();
    setTimeout(connect, 1000);
  };
}

function offline() {
  if (hold) hold.cancel();
  document.body.classList.add("offline");
  $("arm").textContent = "No connection to the arm";
}

setInterval(() => {
  if (ws && ws.readyState === WebSocket.OPEN && Date.now() - heard > SILENT_MS) {
    offline();
    ws.close(); // onclose connects again
  }
}, 500);

function button(id, label, cls, onClick) {
  const b = document.createElement("button");
  b.id = id;
  b.textContent = label;
  if (cls) b.className = cls;
  if (onClick) b.addEventListener("click", onClick);
  return b;
}

function setUp(hello) {
  if (built) return;
  built = true;
  hold = new Hold(send, hello.repeat_ms);
  const tasks = $("tasks");
  for (const t of hello.buttons) {
    const b = button(`task-${t.id}`, t.label, t.ready ? "" : "unset", () =>
      t.objects.length ? choose(t) : send({ t: "task", id: t.id }),
    );
    if (!t.ready) b.setAttribute("aria-description", "not set up yet");
    tasks.append(b);
  }
  const pad = $("pad");
  for (const p of hello.pad) {
    const b = button(`pad-${p.id}`, p.label);
    b.dataset.axis = p.id;
    hold.attach(b, p.id);
    pad.append(b);
  }
  const stepMs = Number(params.get("scan_ms")) || hello.scan_ms;
  scanner = new Scanner(document.body, hold, stepMs);
  const scan = params.has("scan") ? params.get("scan") !== "0" : hello.scan;
  setScanning(scan);
}

function choose(t) {
  const box = $("choose");
  box.replaceChildren(box.firstElementChild);
  $("choose-words").textContent = `${t.label}: which one?`;
  for (const name of t.objects) {
    box.append(
      button(`object-${name}`, name[0].toUpperCase() + name.slice(1), "", () => {
        closeChooser();
        send({ t: "task", id: t.id, object: name });
      }),
    );
  }
  box.append(button("object-back", "Back", "back", closeChooser));
  $("tasks").hidden = true;
  box.hidden = false;
}

function closeChooser() {
  $("choose").hidden = true;
  $("tasks").hidden = false;
}

function setScanning(on) {
  scanner.set(on);
  $("scan").textContent = `Switch scanning: ${on ? "on" : "off"}`;
  $("scan").setAttribute("aria-pressed", String(on));
}

function show(v) {
  view = v;
  document.body.classList.toggle("offline", !v.connected);
  $("arm").textContent = v.arm;
  $("release-stop").hidden = !v.estop;
  const n = v.notice;
  $("notice").hidden = !n;
  if (n) {
    $("notice").classList.toggle("good", !n.trouble);
    $("notice-text").textContent = n.text;
    $("notice-details").textContent = n.details;
    $("notice-more").hidden = !n.details;
  }
  const task = v.task;
  $("task").hidden = !task;
  if (task) {
    $("task-words").textContent = task.words;
    const pct = Math.round(100 * task.progress);
    $("task-fill").style.width = `${pct}%`;
    $("task-bar").setAttribute("aria-valuenow", String(pct));
    $("pause").hidden = task.state !== "running";
    $("resume").hidden = task.state !== "paused";
    $("done").hidden = !task.can_finish;
  }
  for (const b of $("tasks").children) b.disabled = Boolean(task);
  $("level").textContent = v.level ? `Speed ${v.level} of ${v.levels}` : "Speed –";
  $("slower").disabled = !v.level || v.level <= 1;
  $("faster").disabled = v.level >= v.levels;
}

// STOP acts when pressed, not when let go (a click comes on release); the click stays
// for the keyboard and the switch. A second e-stop changes nothing.
const stop = () => {
  if (hold) hold.stop();
  send({ t: "stop" });
};
$("stop").addEventListener("pointerdown", stop);
$("stop").addEventListener("click", stop);
$("release-stop").addEventListener("click", () => send({ t: "release_stop" }));
$("pause").addEventListener("click", () => send({ t: "control", action: "pause" }));
$("resume").addEventListener("click", () => send({ t: "control", action: "resume" }));
$("cancel").addEventListener("click", () => send({ t: "control", action: "cancel" }));
$("done").addEventListener("click", () => send({ t: "control", action: "done" }));
$("slower").addEventListener("click", () => view && send({ t: "level", level: view.level - 1 }));
$("faster").addEventListener("click", () => view && send({ t: "level", level: view.level + 1 }));
// (an unknown level, 0, goes to 1: the slowest)
$("scan").addEventListener("click", () => setScanning(!scanner.on));

connect();
