// stalm view: the scene, the timeline, the plan and the search, from the embedded data.
// Every text from the result file goes into the page with textContent, never as HTML.
(function () {
  "use strict";
  const D = JSON.parse(document.getElementById("stalm-data").textContent);
  const frames = D.frames || { action: [-1], poses: [[]], arm: [[]] };
  const nFrames = frames.action.length;
  const plan = D.plan || [];
  const FRAME_MS = 90;

  function el(tag, text, cls) {
    const node = document.createElement(tag);
    if (text !== undefined && text !== null) node.textContent = String(text);
    if (cls) node.className = cls;
    return node;
  }
  function actionText(action) {
    if (!Array.isArray(action) || action.length === 0) return String(action);
    return action[0] + "(" + action.slice(1).join(", ") + ")";
  }
  function num(value, digits) {
    return typeof value === "number" && isFinite(value) ? value.toFixed(digits) : "?";
  }

  // ------------------------------------------------------------------ header
  const r = D.result || {};
  document.getElementById("title").textContent =
    "stalm view: " + D.problem + " with " + (r.planner || "?") + " (seed " + r.seed + ")";
  const t = r.times || {};
  const c = r.counters || {};
  document.getElementById("summary").textContent =
    (r.success ? "solved" : "not solved (" + r.termination + ")") +
    " with " + plan.length + " actions in " + num(t.total, 1) + " s" +
    (D.proposer ? "; task plans from " + D.proposer : "") +
    "; simulations " + (c.simulations ?? "?") + ", replans " + (c.replans ?? "?") +
    ", T calls " + (c.transitions ?? "?") + (D.source ? "; file " + D.source : "");
  document.getElementById("goal").textContent = "Goal: " + (D.goal || []).join(" and ");
  const notes = document.getElementById("notes");
  for (const note of D.notes || []) notes.appendChild(el("li", note));

  // ------------------------------------------------------------------ the 3D scene
  const scene = D.scene;
  const moving = scene.moving;
  function rotate(q, v) {
    // v + 2w(q x v) + 2 q x (q x v), q = (x, y, z, w)
    const [qx, qy, qz, qw] = q;
    const [vx, vy, vz] = v;
    const tx = 2 * (qy * vz - qz * vy), ty = 2 * (qz * vx - qx * vz), tz = 2 * (qx * vy - qy * vx);
    return [
      vx + qw * tx + (qy * tz - qz * ty),
      vy + qw * ty + (qz * tx - qx * tz),
      vz + qw * tz + (qx * ty - qy * tx),
    ];
  }
  function movingAt(f) {
    const poses = frames.poses[f];
    const xs = new Array(moving.x.length), ys = new Array(moving.x.length), zs = new Array(moving.x.length);
    scene.bodies.forEach(function (body, b) {
      const o = 7 * b;
      const pos = [poses[o], poses[o + 1], poses[o + 2]];
      const q = [poses[o + 3], poses[o + 4], poses[o + 5], poses[o + 6]];
      for (let v = body.start; v < body.start + body.count; v++) {
        const w = rotate(q, [moving.x[v], moving.y[v], moving.z[v]]);
        xs[v] = w[0] + pos[0]; ys[v] = w[1] + pos[1]; zs[v] = w[2] + pos[2];
      }
    });
    return [xs, ys, zs];
  }
  function armAt(f) {
    const pts = frames.arm[f] || [];
    return [pts.map((p) => (p ? p[0] : null)), pts.map((p) => (p ? p[1] : null)), pts.map((p) => (p ? p[2] : null))];
  }
  function mesh(m, extra) {
    return Object.assign({
      type: "mesh3d", x: m.x, y: m.y, z: m.z, i: m.i, j: m.j, k: m.k, facecolor: m.facecolor,
      flatshading: true, hoverinfo: "skip", showscale: false,
      lighting: { ambient: 0.6, diffuse: 0.6, specular: 0.05, roughness: 0.9 },
    }, extra);
  }
  const [mx, my, mz] = movingAt(0);
  const [ax, ay, az] = armAt(0);
  const traces = [
    mesh(scene.ground, { name: "floor and regions" }),
    mesh(scene.walls, { name: "walls", opacity: 0.25 }),
    mesh(Object.assign({}, moving, { x: mx, y: my, z: mz }), { name: "objects, doors, robot" }),
    {
      type: "scatter3d", mode: "lines+markers", x: ax, y: ay, z: az, name: "arm",
      line: { color: "rgb(70,70,80)", width: 9 }, marker: { size: 3, color: "rgb(40,40,40)" },
      connectgaps: false, hoverinfo: "skip",
    },
  ];
  const [[x0, y0], [x1, y1]] = D.floor;
  const axis = { visible: false, showspikes: false };
  const layout = {
    margin: { l: 0, r: 0, t: 0, b: 0 },
    showlegend: false,
    paper_bgcolor: "rgb(250,250,250)",
    scene: {
      xaxis: Object.assign({ range: [x0 - 0.2, x1 + 0.2] }, axis),
      yaxis: Object.assign({ range: [y0 - 0.2, y1 + 0.2] }, axis),
      zaxis: Object.assign({ range: [-0.05, 2.6] }, axis),
      aspectmode: "manual",
      aspectratio: { x: 1, y: (y1 - y0) / (x1 - x0), z: 2.65 / (x1 - x0) },
      camera: { eye: { x: 0.38, y: -0.68, z: 0.62 }, up: { x: 0, y: 0, z: 1 } },
      dragmode: "turntable",
      uirevision: "keep",
    },
    uirevision: "keep",
  };
  const gd = document.getElementById("stalm-scene");
  const config = { displaylogo: false, responsive: true, scrollZoom: true };

  // ------------------------------------------------------------------ the timeline
  const slider = document.getElementById("slider");
  const label = document.getElementById("frame-label");
  const playButton = document.getElementById("play");
  slider.max = String(nFrames - 1);
  const state = { frame: 0, playing: false, timer: null, drawing: Promise.resolve(), rendered: 0 };

  function firstFrameOf(action) {
    const f = frames.action.indexOf(action);
    return f < 0 ? nFrames - 1 : f;
  }
  const times = frames.time || [];
  const robotEnd = times.length ? times[times.length - 1] : null;
  function robotTime(f) {
    // seconds of robot time: the plan timed under the robot's limits, as stalm export does
    if (typeof times[f] !== "number") return "";
    return ", " + num(times[f], 1) + " s of " + num(robotEnd, 1) + " s robot time";
  }
  function showLabel(f) {
    const a = frames.action[f];
    label.textContent = "frame " + (f + 1) + "/" + nFrames + robotTime(f) + ": " +
      (a < 0 ? "the initial state" : "action " + (a + 1) + "/" + plan.length + " " +
        actionText(plan[a] ? plan[a].action : "?"));
    document.querySelectorAll("#plan tbody tr").forEach(function (row, index) {
      row.classList.toggle("current", index === a);
    });
  }
  function setFrame(f) {
    f = Math.max(0, Math.min(nFrames - 1, Math.round(f)));
    state.frame = f;
    slider.value = String(f);
    showLabel(f);
    document.body.dataset.frame = String(f);
    const [xs, ys, zs] = movingAt(f);
    const [axs, ays, azs] = armAt(f);
    state.drawing = Plotly.restyle(gd, { x: [xs, axs], y: [ys, ays], z: [zs, azs] }, [2, 3]).then(
      function () { state.rendered = f; document.body.dataset.rendered = String(f); });
    return state.drawing;
  }
  function pause() {
    state.playing = false;
    if (state.timer) clearTimeout(state.timer);
    state.timer = null;
    playButton.textContent = "play";
  }
  function tick() {
    if (!state.playing) return;
    if (state.frame >= nFrames - 1) { pause(); return; }
    const speed = Number(document.getElementById("speed").value) || 1;
    setFrame(state.frame + speed).then(function () {
      if (state.playing) state.timer = setTimeout(tick, FRAME_MS);
    });
  }
  function play() {
    if (nFrames < 2) return;
    if (state.frame >= nFrames - 1) setFrame(0);
    state.playing = true;
    playButton.textContent = "pause";
    state.timer = setTimeout(tick, FRAME_MS);
  }
  function stepAction(direction) {
    pause();
    const a = frames.action[state.frame];
    if (direction > 0) {
      const next = frames.action.findIndex((x) => x > a);
      return setFrame(next < 0 ? nFrames - 1 : next);
    }
    const start = firstFrameOf(a);
    if (state.frame > start) return setFrame(start);
    return setFrame(a <= 0 ? 0 : firstFrameOf(a - 1));
  }
  playButton.addEventListener("click", function () { state.playing ? pause() : play(); });
  document.getElementById("next-action").addEventListener("click", function () { stepAction(1); });
  document.getElementById("prev-action").addEventListener("click", function () { stepAction(-1); });
  document.getElementById("next-frame").addEventListener("click", function () { pause(); setFrame(state.frame + 1); });
  document.getElementById("prev-frame").addEventListener("click", function () { pause(); setFrame(state.frame - 1); });
  slider.addEventListener("input", function () { pause(); setFrame(Number(slider.value)); });
  document.addEventListener("keydown", function (event) {
    if (event.target && event.target.tagName === "INPUT") return;
    if (event.key === " ") { event.preventDefault(); state.playing ? pause() : play(); }
    else if (event.key === "ArrowRight") { pause(); setFrame(state.frame + 1); }
    else if (event.key === "ArrowLeft") { pause(); setFrame(state.frame - 1); }
  });

  // ------------------------------------------------------------------ the plan
  const planBody = document.querySelector("#plan tbody");
  plan.forEach(function (row, index) {
    const tr = document.createElement("tr");
    tr.appendChild(el("td", index + 1));
    tr.appendChild(el("td", actionText(row.action), "mono"));
    const params = el("td");
    params.appendChild(el("div", row.summary || "(not replayed)"));
    if (Array.isArray(row.robot_time)) {
      params.appendChild(el("div", "robot time " + num(row.robot_time[0], 1) + "-" +
        num(row.robot_time[1], 1) + " s (timed under the robot's limits, as stalm export)", "hint"));
    }
    const more = el("details");
    more.appendChild(el("summary", "all parameters"));
    more.appendChild(el("pre", JSON.stringify(row.params, null, 1), "mono"));
    params.appendChild(more);
    tr.appendChild(params);
    tr.addEventListener("click", function (event) {
      if (event.target.closest("details")) return;
      pause();
      setFrame(firstFrameOf(index));
    });
    planBody.appendChild(tr);
  });
  const rp = D.replay || {};
  document.getElementById("replay").textContent = rp.reached_goal
    ? "Replayed in a fresh scene: the " + rp.steps + " actions reach the goal."
    : "Replayed in a fresh scene: " + (rp.reason || "the goal is not reached") +
      (rp.failed_step !== null && rp.failed_step !== undefined ? " (action " + (rp.failed_step + 1) + ")" : "") + ".";
  const failures = Object.entries(D.llm_plan_failures || {});
  document.getElementById("failures").textContent = failures.length
    ? failures.map(([kind, n]) => kind + ": " + n).join(", ")
    : "none";

  // ------------------------------------------------------------------ the search, per step
  const stepsDiv = document.getElementById("steps");
  function planRow(p) {
    const tr = document.createElement("tr");
    tr.appendChild(el("td", (p.index ?? 0) + 1));
    const actions = el("td");
    if (p.unparseable) {
      actions.appendChild(el("span", "unreadable reply: " + p.unparseable, "chip failed"));
    }
    if (p.no_plan) {
      actions.appendChild(el("span", "no plan found: " + p.no_plan, "chip failed"));
    }
    (p.actions || []).forEach(function (a, i) {
      let cls = "untried";
      if (p.failed_step === i) cls = "failed";
      else if (i < (p.feasible_steps ?? 0)) cls = "ok";
      else if (p.truncated && i === (p.feasible_steps ?? 0)) cls = "cut";
      actions.appendChild(el("span", actionText(a), "chip " + cls));
    });
    tr.appendChild(actions);
    tr.appendChild(el("td", p.reached_goal ? "reached the goal" : p.kind || "", "kind"));
    const why = el("td");
    if (p.reason) {
      why.appendChild(el("div", "step " + ((p.failed_step ?? 0) + 1) + ": " + p.reason.kind + ": " + p.reason.detail));
      if ((p.reason.blockers || []).length) why.appendChild(el("div", "blocked by " + p.reason.blockers.join(", ")));
    } else if (p.detail) {
      why.appendChild(el("div", p.detail));
    }
    if (p.kind && p.concretize_kind && p.kind !== p.concretize_kind) {
      why.appendChild(el("div", "(Concretize: " + p.concretize_kind + "; its first step was occluded in the prompt's predicates)"));
    }
    tr.appendChild(why);
    return tr;
  }
  function treeTable(tree) {
    const wrap = el("div");
    wrap.appendChild(el("p",
      "Root N = " + tree.root_visits + " (" + tree.root_visits_before + " kept from the previous step); " +
      tree.discrete_nodes + " discrete nodes, " + tree.kappa_children + " sampled children; " +
      tree.untried_root_actions + " of " + tree.root_actions + " root actions never tried. " +
      "Marked 'warm': put in the tree by this step's warm start (Concretize's plans)."));
    const table = el("table");
    const head = el("tr");
    ["root action", "N", "Q", "feasible / sampled \u03ba", "then (most visited, from its most visited \u03ba)"]
      .forEach((h) => head.appendChild(el("th", h)));
    table.appendChild(el("thead")).appendChild(head);
    const body = el("tbody");
    for (const a of tree.actions || []) {
      const tr = document.createElement("tr");
      const name = el("td", actionText(a.action), "mono");
      if (a.warm) { name.appendChild(document.createTextNode(" ")); name.appendChild(el("span", "warm", "warm")); }
      tr.appendChild(name);
      tr.appendChild(el("td", a.n));
      tr.appendChild(el("td", num(a.q, 2)));
      tr.appendChild(el("td", a.feasible_kappas + " / " + a.kappas));
      const kids = el("td", null, "children");
      (a.children || []).forEach(function (k) {
        const item = el("div", actionText(k.action) + "  N " + k.n + ", Q " + num(k.q, 2), "mono");
        if (k.warm) { item.appendChild(document.createTextNode(" ")); item.appendChild(el("span", "warm", "warm")); }
        kids.appendChild(item);
      });
      tr.appendChild(kids);
      body.appendChild(tr);
    }
    table.appendChild(body);
    wrap.appendChild(table);
    return wrap;
  }
  if (!Array.isArray(D.step_log)) {
    stepsDiv.appendChild(el("p", "Not recorded in this result file (see the note at the top)."));
  } else if (D.step_log.length === 0) {
    stepsDiv.appendChild(el("p", "The planner took no step."));
  }
  (D.step_log || []).forEach(function (step, number) {
    const box = el("details", null, "step");
    if (number === 0) box.open = true;
    const executed = step.executed ?? 0;
    const first = step.step ?? 0;
    const title = "Real step " + (number + 1) + " (after " + first + " executed actions): " +
      (executed > 0
        ? "executed " + (executed === 1 ? "action " + (first + 1) : "actions " + (first + 1) + "\u2013" + (first + executed))
        : "executed nothing");
    const summary = el("summary", title);
    if (executed > 0) {
      const go = el("button", "show in the scene", "goto");
      go.addEventListener("click", function (event) { event.preventDefault(); pause(); setFrame(firstFrameOf(first)); });
      summary.appendChild(go);
    }
    box.appendChild(summary);
    box.appendChild(el("p", "Why: " + ((D.decisions || {})[step.decision] || step.decision || "not recorded"), "decision"));
    const proposals = step.proposals || [];
    if (proposals.length === 0) box.appendChild(el("p", "No task plans proposed (a planner without a proposer)."));
    proposals.forEach(function (round) {
      box.appendChild(el("h3", "Task plans, round " + (round.round + 1) +
        (round.feedback_facts ? " (told " + round.feedback_facts + " facts learned from failures)" : "")));
      const table = el("table");
      const head = el("tr");
      ["#", "task plan (green: feasible, red: failed, grey: not tried)", "Figure 5 kind", "why it failed"]
        .forEach((h) => head.appendChild(el("th", h)));
      table.appendChild(el("thead")).appendChild(head);
      const body = el("tbody");
      (round.plans || []).forEach((p) => body.appendChild(planRow(p)));
      table.appendChild(body);
      box.appendChild(table);
    });
    box.appendChild(el("h3", "Search tree"));
    if (step.tree) box.appendChild(treeTable(step.tree));
    else box.appendChild(el("p", "No tree search in this step."));
    stepsDiv.appendChild(box);
  });

  // ------------------------------------------------------------------ start
  window.stalmView = {
    frames: nFrames,
    get frame() { return state.frame; },
    get playing() { return state.playing; },
    setFrame: setFrame, play: play, pause: pause, stepAction: stepAction,
    drawn: function () { return state.drawing; },
  };
  Plotly.newPlot(gd, traces, layout, config).then(function () {
    showLabel(0);
    document.body.dataset.frame = "0";
    document.body.dataset.ready = "1";
  });
})();
