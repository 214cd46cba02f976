// pipeflow viewer: builds a simulation spec from the form, runs it on this service,
// draws the tip displacement, damping and frequency with uPlot (vendored, works offline),
// and shows the API's problem details next to the offending field.
"use strict";

(function () {
  const API = {
    simulate: "v1/simulations",
    result: (key) => "v1/results/" + encodeURIComponent(key),
  };
  const form = document.getElementById("spec-form");
  const statusEl = document.getElementById("status");
  const runButton = document.getElementById("run");
  const charts = {};
  const state = { result: null, key: null };
  window.pipeflowViewer = { charts, state };

  // ---- form <-> spec -------------------------------------------------------------------

  function numberOrRaw(text) {
    // send what the user typed when it is not a number: the API names the field
    const s = String(text).trim();
    if (s === "") return null;
    const x = Number(s);
    return Number.isFinite(x) ? x : s;
  }

  function value(name) {
    return numberOrRaw(form.elements.namedItem(name).value);
  }

  function profile(prefix) {
    const kind = form.elements.namedItem(prefix + ".kind").value;
    if (kind === "constant") return { kind, value: value(prefix + ".value") };
    if (kind === "polynomial") {
      const text = form.elements.namedItem(prefix + ".coefficients").value;
      const coefficients = text.split(/[,\s]+/).filter((s) => s !== "").map(numberOrRaw);
      return { kind, coefficients };
    }
    return {
      kind,
      mean: value(prefix + ".mean"),
      amplitude: value(prefix + ".amplitude"),
      frequency: value(prefix + ".frequency"),
      phase: value(prefix + ".phase"),
    };
  }

  function specFromForm() {
    return {
      pipe: {
        E: value("pipe.E"), I: value("pipe.I"), L: value("pipe.L"),
        M1: value("pipe.M1"), M2: value("pipe.M2"),
      },
      rotation: { omega0: profile("rotation.omega0") },
      flow: { velocity: profile("flow.velocity") },
      initial: { u0: value("initial.u0"), du0: value("initial.du0") },
      modes: value("modes"),
      time: { t_end: value("time.t_end"), samples: value("time.samples") },
      method: form.elements.namedItem("method").value,
    };
  }

  function show(x) {
    // 7800000000 -> "7.8e9", as a person would type it
    if (typeof x !== "number" || x === 0) return String(x);
    const a = Math.abs(x);
    return a >= 1e6 || a < 1e-3 ? x.toExponential().replace("e+", "e") : String(x);
  }

  function setField(name, v) {
    const el = form.elements.namedItem(name);
    if (el && v !== undefined && v !== null) el.value = Array.isArray(v) ? v.map(show).join(", ") : show(v);
  }

  function fillForm(spec) {
    for (const k of ["E", "I", "L", "M1", "M2"]) setField("pipe." + k, spec.pipe && spec.pipe[k]);
    const profiles = [
      ["rotation.omega0", spec.rotation && spec.rotation.omega0],
      ["flow.velocity", spec.flow && spec.flow.velocity],
    ];
    for (const [prefix, p] of profiles) {
      if (!p) continue;
      setField(prefix + ".kind", p.kind);
      for (const k of ["value", "coefficients", "mean", "amplitude", "frequency", "phase"]) {
        setField(prefix + "." + k, p[k]);
      }
    }
    if (spec.initial) { setField("initial.u0", spec.initial.u0); setField("initial.du0", spec.initial.du0); }
    setField("modes", spec.modes);
    if (spec.time) { setField("time.t_end", spec.time.t_end); setField("time.samples", spec.time.samples); }
    setField("method", spec.method);
    showKinds();
  }

  function showKinds() {
    for (const fs of form.querySelectorAll("fieldset.profile")) {
      const kind = form.elements.namedItem(fs.dataset.profile + ".kind").value;
      for (const div of fs.querySelectorAll(".kind")) div.hidden = div.dataset.kind !== kind;
    }
  }

  // ---- errors next to fields -----------------------------------------------------------

  function clearErrors() {
    for (const el of document.querySelectorAll("[data-error-for]")) el.textContent = "";
    for (const el of form.querySelectorAll(".invalid")) el.classList.remove("invalid");
  }

  function errorSlot(field) {
    // the longest form field that is a prefix of the API's dotted path
    // (e.g. "flow.velocity.coefficients.1" -> "flow.velocity.coefficients")
    const parts = (field || "").split(".");
    for (let n = parts.length; n > 0; n--) {
      const name = parts.slice(0, n).join(".");
      const slot = form.querySelector('[data-error-for="' + CSS.escape(name) + '"]');
      if (slot) return { slot, input: form.querySelector('[data-field="' + CSS.escape(name) + '"]') };
    }
    return { slot: document.getElementById("form-error"), input: null };
  }

  function showProblem(problem) {
    const errors = problem.errors && problem.errors.length ? problem.errors
      : [{ field: problem.field || null, message: problem.detail || problem.title }];
    for (const e of errors) {
      const { slot, input } = errorSlot(e.field);
      const text = slot.id === "form-error" && e.field ? e.field + ": " + e.message : e.message;
      slot.textContent = slot.textContent ? slot.textContent + "; " + text : text;
      if (input) input.classList.add("invalid");
    }
    statusEl.textContent = problem.title || "error";
  }

  // ---- charts ----------------------------------------------------------------------------

  const COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"];

  function drawChart(id, xLabel, yLabel, x, series) {
    const host = document.getElementById(id);
    if (charts[id]) { charts[id].destroy(); delete charts[id]; }
    const width = Math.max(320, Math.min(host.clientWidth || 800, 1000));
    const opts = {
      width, height: 260,
      scales: { x: { time: false } },
      axes: [{ label: xLabel }, { label: yLabel, size: 80 }],
      series: [{ label: xLabel }].concat(series.map((s, i) => ({
        label: s.label, stroke: COLORS[i % COLORS.length], width: 1.2,
      }))),
      cursor: { drag: { x: true, y: false } },
    };
    charts[id] = new uPlot(opts, [x].concat(series.map((s) => s.y)), host);
    host.dataset.points = String(x.length);
  }

  function render(result) {
    state.result = result;
    document.getElementById("results").hidden = false;
    drawChart("chart-tip", "t [s]", "u(L, t) [m]", result.t,
      [{ label: "tip displacement [m]", y: result.tip_displacement }]);
    const ev = result.eigenvalues;
    drawChart("chart-damping", "t [s]", "σ [1/s]", ev.t,
      ev.modes.map((m) => ({ label: "σ mode " + m.mode + " [1/s]", y: m.sigma })));
    drawChart("chart-frequency", "t [s]", "ω [rad/s]", ev.t,
      [{ label: "ω mode 1 [rad/s]", y: ev.modes[0].omega }]);
    const list = document.getElementById("warnings");
    list.textContent = "";
    for (const w of result.warnings || []) {
      const li = document.createElement("li");
      li.textContent = w;
      list.appendChild(li);
    }
  }

  function share(key, spec) {
    const url = new URL(window.location.href);
    url.search = "";
    url.searchParams.set("key", key);
    if (spec) url.searchParams.set("spec", JSON.stringify(spec));
    const link = document.getElementById("share-link");
    link.href = url.toString();
    link.textContent = key.slice(0, 12) + "…";
    document.getElementById("csv-history").href = API.result(key) + "?format=csv";
    document.getElementById("csv-eigen").href = API.result(key) + "?format=csv&table=eigenvalues";
    window.history.replaceState(null, "", url.toString());
  }

  // ---- API calls -------------------------------------------------------------------------

  async function problemOf(response) {
    try {
      return await response.json();
    } catch (e) {
      return { title: response.status + " " + response.statusText };
    }
  }

  async function run(event) {
    if (event) event.preventDefault();
    clearErrors();
    const spec = specFromForm();
    runButton.disabled = true;
    statusEl.textContent = "running…";
    const started = performance.now();
    try {
      const response = await fetch(API.simulate, {
        method: "POST",
        headers: { "Content-Type": "application/json", Accept: "application/json" },
        body: JSON.stringify(spec),
      });
      if (!response.ok) { showProblem(await problemOf(response)); return; }
      const result = await response.json();
      state.key = result.key;
      render(result);
      share(result.key, spec);
      const seconds = ((performance.now() - started) / 1000).toFixed(2);
      statusEl.textContent = "done (" + result.status + ", " + (result.cached ? "cached" : "computed")
        + " in " + seconds + " s)";
    } catch (e) {
      statusEl.textContent = "network error: " + e.message;
    } finally {
      runButton.disabled = false;
    }
  }

  async function loadShared() {
    const params = new URLSearchParams(window.location.search);
    let spec = null;
    if (params.get("spec")) {
      try { spec = JSON.parse(params.get("spec")); fillForm(spec); } catch (e) {
        spec = null;
        statusEl.textContent = "bad spec in link";
      }
    }
    const key = params.get("key");
    if (!key) return;
    statusEl.textContent = "loading " + key.slice(0, 12) + "…";
    const response = await fetch(API.result(key), { headers: { Accept: "application/json" } });
    if (!response.ok) { showProblem(await problemOf(response)); return; }
    const result = await response.json();
    state.key = key;
    render(result);
    share(key, spec);
    statusEl.textContent = "loaded result " + key.slice(0, 12) + "…";
  }

  async function loadMethods() {
    // the solvers this server offers (the spec's method enum), e.g. magnus where installed
    try {
      const doc = await (await fetch("openapi.json")).json();
      const names = doc.components.schemas.SimulationSpec.properties.method.enum;
      const select = form.elements.namedItem("method");
      const current = select.value;
      if (!Array.isArray(names) || !names.includes(current)) return;
      select.textContent = "";
      for (const n of names) select.add(new Option(n, n, n === current, n === current));
    } catch (e) { /* keep the built-in list */ }
  }

  form.addEventListener("submit", run);
  form.addEventListener("change", (e) => { if (e.target.name && e.target.name.endsWith(".kind")) showKinds(); });
  showKinds();
  loadMethods();
  window.pipeflowViewer.ready = loadShared().catch((e) => { statusEl.textContent = String(e); });
})();
