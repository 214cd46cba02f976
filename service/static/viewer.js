// pipeflow viewer: a simulation form generated from the request schema in /openapi.json
// (SchemaForm), a run on this service, and uPlot charts (vendored, works offline) of the
// tip displacement, damping and frequency.  An unstable run says so in a banner (first
// time of instability, growth rate of the least-stable branch) and draws a diverging tip
// on a symmetric-log (asinh) scale with readable axis labels.  A forced run (loads) says
// which loads were applied (the result echoes them); a start at rest (u0 = 0: zero initial
// tip) is a forced vibration, drawn on a linear axis unless the library calls it unstable.
// A run that diverged after a few output samples says so and how to get more (a t_end at
// the divergence time, offered as a button).  The result of a Run is scrolled into view.
// The frequency chart's axis is in rad/s, Hz or rpm (the data stay rad/s); the result links
// to its report (HTML, PDF).
"use strict";

(function () {
  const SF = window.SchemaForm;
  const P = window.PipeflowPages;
  const { tick, finite } = P;
  const API = { simulate: "v1/simulations", result: P.resultUrl };
  const form = document.getElementById("spec-form");
  const host = document.getElementById("fields");
  const statusEl = document.getElementById("status");
  const runButton = document.getElementById("run");
  const formError = document.getElementById("form-error");
  const charts = {};
  const state = { result: null, key: null, doc: null, schema: null, run: 0 };
  window.pipeflowViewer = { charts, state };
  const page = P.page({ form, formError, status: statusEl, button: runButton, state, progress: null });

  // ---- the form, from the schema --------------------------------------------------------

  function initialValues(schema) {
    // the schema's example (the paper's case), with the method left to the API's default
    const example = JSON.parse(JSON.stringify((schema.examples || [])[0] || {}));
    delete example.method;
    return example;
  }

  function specFromForm() {
    return SF.collect(host, state.doc, state.schema);
  }

  // ---- charts ----------------------------------------------------------------------------

  const COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"];
  //: the frequency axis's units, each per rad/s (Hz: cycles per second, rpm: per minute)
  const PER_RAD_S = { "rad/s": 1, Hz: 1 / (2 * Math.PI), rpm: 60 / (2 * Math.PI) };

  // The symmetric-log (asinh) tip scale: the data are drawn as asinh(u / u_lin) on a
  // linear axis (u_lin: the initial tip amplitude, below which the axis is linear), with
  // ticks placed at 0 and +-10^k and labelled with u itself.  uPlot's own asinh scale finds
  // no ticks for ranges beyond about 1e3, which a diverging tip (1e304 m) far exceeds.
  function symlog(linear, peak) {
    const fwd = (v) => (v === null ? null : Math.asinh(v / linear));
    const back = (y) => Math.sinh(y) * linear;
    const top = Math.max(peak, linear);
    const range = () => [-1.05 * fwd(top), 1.05 * fwd(top)];
    const splits = (u, axis, min, max) => {
      const kmax = Math.floor(Math.log10(top));
      const kmin = Math.min(kmax, Math.ceil(Math.log10(linear)));
      const stride = Math.max(1, Math.ceil((kmax - kmin + 1) / 4));
      const out = [0];
      for (let k = kmax; k >= kmin; k -= stride) {
        const y = fwd(Math.pow(10, k));
        if (y <= max) out.push(y);
        if (-y >= min) out.push(-y);
      }
      return out.sort((a, b) => a - b);
    };
    return { fwd, back, splits, range, linear };
  }

  function drawChart(id, xLabel, yLabel, x, series, log) {
    const chartHost = document.getElementById(id);
    if (charts[id]) { charts[id].destroy(); delete charts[id]; }
    const width = P.chartWidth(chartHost, 800);
    const label = (y) => tick(log ? log.back(y) : y);
    const yAxis = { label: log ? yLabel + " (sym. log)" : yLabel, size: 80, values: (u, splits) => splits.map(label) };
    if (log) yAxis.splits = log.splits;
    const chart = new uPlot({
      width, height: 260,
      scales: { x: { time: false }, y: log ? { auto: false, range: log.range } : { auto: true } },
      axes: [{ label: xLabel, values: (u, splits) => splits.map(tick) }, yAxis],
      series: [{ label: xLabel }].concat(series.map((s, i) => ({
        label: s.label, stroke: s.stroke || COLORS[i % COLORS.length], width: s.width || 1.2,
        dash: s.dash,
        value: (u, v) => (v === null ? "--" : label(v)),
      }))),
      cursor: { drag: { x: true, y: false } },
    }, [x].concat(series.map((s) => (log ? finite(s.y).map(log.fwd) : finite(s.y)))), chartHost);
    charts[id] = chart;
    chartHost.dataset.points = String(x.length);
    chartHost.dataset.scale = log ? "symlog" : "linear";
  }

  function axisLabels(id) {
    // the y tick labels as drawn (for the page's tests and for a reader of the DOM)
    const c = charts[id];
    return c && c.axes[1]._values ? c.axes[1]._values.slice() : [];
  }
  window.pipeflowViewer.axisLabels = axisLabels;

  function instability(result) {
    // what the result says about growth; keys absent from older results are skipped
    const ev = result.eigenvalues || { modes: [] };
    const diag = result.diagnostics || {};
    const least = (ev.modes || []).find((m) => m.least_stable) || null;
    const rate = typeof diag.max_growth_rate === "number" ? diag.max_growth_rate : null;
    const first = result.first_unstable_time;
    // the library's verdicts (growth above the spectrum's rounding level), not the sign of
    // a rate that may be rounding
    const unstable = (first !== undefined && first !== null)
      || result.status === "overflow" || result.status === "diverging"
      || result.status === "diverged"
      || (result.divergence_time !== undefined && result.divergence_time !== null);
    return { unstable, first, rate, least };
  }

  function banner(result) {
    const el = document.getElementById("unstable");
    const info = instability(result);
    el.hidden = !info.unstable;
    el.textContent = "";
    if (!info.unstable) return;
    const parts = ["Unstable run."];
    if (info.first !== undefined && info.first !== null) {
      parts.push("First unstable at t = " + tick(info.first) + " s (a frozen branch has σ > 0).");
    }
    if (info.rate !== null && info.rate > 0) {
      const mode = info.least ? " (least-stable branch: mode " + info.least.mode + ")" : "";
      parts.push("Growth rate max σ = " + tick(info.rate) + " 1/s" + mode
        + ", e-folding time " + tick(1 / info.rate) + " s.");
    }
    if (result.divergence_time !== undefined && result.divergence_time !== null) {
      const bound = typeof result.divergence_bound === "number"
        ? " |u| ≤ " + tick(result.divergence_bound) + " m" : "";
      const rate = typeof result.divergence_growth_rate === "number"
        ? " (growth rate " + tick(result.divergence_growth_rate) + " 1/s there)" : "";
      parts.push("Diverged: the deflection left the linear model's range" + bound
        + " at t = " + tick(result.divergence_time) + " s" + rate
        + "; the history stops there.");
    }
    if (result.status === "overflow") parts.push("The response overflowed double precision.");
    el.textContent = parts.join(" ");
    el.dataset.firstUnstableTime = info.first === undefined || info.first === null ? "" : String(info.first);
    el.dataset.growthRate = info.rate === null ? "" : String(info.rate);
  }

  //: a diverged run showing fewer output samples than this (and under a quarter of those
  //: requested) is "short": the page says why and how to get more
  const SHORT_RUN = 200;

  function requested(name) {
    // a number of the request as the form holds it (the run's own: the form sent it, or
    // the shared link filled it), NaN when absent
    const input = form.querySelector("input[name='" + name + "']");
    return input ? Number(input.value) : NaN;
  }

  function shortRun(result) {
    // a run that diverged after a few output samples: how many, where it stopped, and the
    // settings that give more (t_end at the divergence time: every requested sample falls
    // before it; a larger divergence bound; a lower velocity or spin stays stable)
    const box = document.getElementById("short-run");
    const shown = (result.t || []).length;
    const samples = requested("time.samples");
    const tEnd = requested("time.t_end");
    const stop = result.divergence_time;
    const short = result.status === "diverged" && typeof stop === "number" && stop > 0
      && shown < SHORT_RUN && !(shown >= samples / 4);
    box.hidden = !short;
    box.dataset.samples = String(shown);
    if (!short) return;
    // t_end at the divergence time, rounded up to two significant digits
    const scale = Math.pow(10, Math.floor(Math.log10(stop)) - 1);
    const suggested = +(Math.ceil(stop / scale) * scale).toPrecision(2);
    box.dataset.suggestedTEnd = String(suggested);
    const text = box.querySelector(".text");
    text.textContent = "The run diverged after " + shown + " output samples"
      + (Number.isFinite(samples) ? " of the " + samples + " requested" : "")
      + ": it stopped at t = " + tick(stop) + " s"
      + (Number.isFinite(tEnd) ? " of t_end = " + tick(tEnd) + " s" : "")
      + ", so the charts show only the start of the growth. For more samples of it, set"
      + " time.t_end to about " + tick(suggested) + " s (the requested samples then fall"
      + " before the divergence) or raise time.samples; a larger output.divergence_bound [m]"
      + " follows it further (within the linear model's range); a lower flow velocity or"
      + " spin keeps the pipe stable.";
    const button = box.querySelector("button");
    button.textContent = "Run again with t_end = " + tick(suggested) + " s";
  }

  function tipScale(result) {
    const choice = document.getElementById("tip-scale").value;
    const y = finite(result.tip_displacement).filter((v) => v !== null);
    const peak = y.reduce((m, v) => Math.max(m, Math.abs(v)), 0);
    const initial = Math.abs(finite([result.initial_tip_displacement])[0] || y[0] || 0);
    // below the linear threshold the axis is linear: the initial tip amplitude, or for a
    // start at rest (a forced run) the early response (first 5 % of the samples), or a
    // millionth of the peak; 1e-9 m for an all-zero history (no log of zero, no 0 / 0)
    let linear = initial;
    if (!(linear > 0)) {
      const early = y.slice(0, Math.max(2, Math.ceil(y.length / 20)));
      linear = early.reduce((m, v) => Math.max(m, Math.abs(v)), 0) || peak * 1e-6;
    }
    if (!(linear > 0)) linear = 1e-9;
    // growth past 100 x the initial amplitude is divergence only when there was one; from
    // rest any response is growth from zero, so there only the library's verdict counts
    const diverging = instability(result).unstable || (initial > 0 && peak > 100 * initial);
    const log = choice === "symlog" || (choice === "auto" && diverging);
    return log ? symlog(linear, peak) : null;
  }

  // ---- the loads of a forced run (echoed by the result) ------------------------------

  function profileText(p, unit) {
    const S = SF.show;
    const u = unit ? " " + unit : "";
    if (!p || typeof p !== "object") return String(p);
    if (p.kind === "constant") return S(p.value) + u;
    if (p.kind === "harmonic") {
      const wave = S(p.amplitude) + " sin(" + S(p.frequency) + " t" + (p.phase ? " + " + S(p.phase) : "") + ")";
      return (p.mean ? S(p.mean) + " + " : "") + wave + u;
    }
    if (p.kind === "polynomial") {
      const terms = (p.coefficients || []).map((c, k) => S(c) + (k === 0 ? "" : k === 1 ? " t" : " t^" + k));
      return terms.join(" + ") + u;
    }
    if (p.kind === "table") {
      const t = p.t || [];
      return "table of " + t.length + " values" + u + " over t = " + S(t[0]) + " … " + S(t[t.length - 1])
        + " s (" + p.interpolation + (p.after ? ", then " + (p.after === "hold" ? "held" : "zero") : "") + ")";
    }
    if (p.kind === "half_sine") {
      return "half-sine pulse of " + S(p.peak) + u + " from t = " + S(p.start) + " s for " + S(p.duration) + " s";
    }
    return JSON.stringify(p);
  }

  function loadText(load) {
    // "point_force: position 0.025 m, force 1e-5 sin(244 t) N", the fields and units from
    // the request schema's load kinds
    const doc = state.doc;
    const items = doc && state.schema.properties.loads ? SF.deref(doc, state.schema.properties.loads.items) : null;
    const ref = items && items.discriminator && items.discriminator.mapping[load.kind];
    const variant = ref ? SF.deref(doc, { $ref: ref }) : { properties: {} };
    const parts = [];
    for (const [name, value] of Object.entries(load)) {
      if (name === "kind") continue;
      const sub = SF.deref(doc, variant.properties[name] || {});
      const unit = SF.unitOf(sub);
      if (value === null || value === undefined) continue;
      parts.push(name + " " + (typeof value === "object" ? profileText(value, unit) : SF.show(value) + (unit ? " " + unit : "")));
    }
    return load.kind.replace(/_/g, " ") + ": " + parts.join(", ");
  }

  function showLoads(result) {
    const box = document.getElementById("loads-applied");
    const list = box.querySelector("ol");
    list.textContent = "";
    const loads = Array.isArray(result.loads) ? result.loads : [];
    box.hidden = loads.length === 0;
    box.dataset.count = String(loads.length);
    for (const load of loads) {
      const li = document.createElement("li");
      li.textContent = loadText(load);
      li.dataset.kind = load.kind;
      list.appendChild(li);
    }
    const relative = loads.some((l) => l.kind === "base_acceleration");
    box.querySelector(".note").hidden = !relative;
    const start = document.getElementById("start-note");
    const initial = result.initial_tip_displacement;
    start.hidden = !(loads.length && initial === 0);
  }

  function render(result) {
    state.result = result;
    document.getElementById("results").hidden = false;
    banner(result);
    shortRun(result);
    showLoads(result);
    const tipSeries = [{ label: "tip displacement [m]", y: result.tip_displacement }];
    if (result.status === "diverged" && typeof result.divergence_bound === "number") {
      // the linear model's range, drawn where the run was stopped
      const b = result.divergence_bound;
      tipSeries.push({ label: "+bound [m]", y: result.t.map(() => b), stroke: "#888", dash: [6, 4] });
      tipSeries.push({ label: "−bound [m]", y: result.t.map(() => -b), stroke: "#888", dash: [6, 4] });
    }
    drawChart("chart-tip", "t [s]", "u(L, t) [m]", result.t, tipSeries, tipScale(result));
    const ev = result.eigenvalues;
    drawChart("chart-damping", "t [s]", "σ [1/s]", ev.t, ev.modes.map((m) => ({
      label: "σ mode " + m.mode + (m.least_stable ? " (least stable)" : "") + " [1/s]",
      y: m.sigma,
      stroke: m.least_stable ? "#c0392b" : undefined,
      width: m.least_stable ? 2.5 : undefined,
    })));
    // an unstable run: the least stable branch next to the fundamental (the flutter branch
    // is often not mode 1; at v = 40 m/s it is mode 5)
    const unit = document.getElementById("frequency-unit").value || "rad/s";
    const inUnit = (omega) => omega.map((w) => (typeof w === "number" ? w * PER_RAD_S[unit] : w));
    const freq = [{ label: "ω mode " + ev.modes[0].mode + " [" + unit + "]", y: inUnit(ev.modes[0].omega) }];
    const least = instability(result).least;
    if (instability(result).unstable && least && least !== ev.modes[0]) {
      freq.push({ label: "ω mode " + least.mode + " (least stable) [" + unit + "]", y: inUnit(least.omega),
        stroke: "#c0392b", width: 2.5 });
    }
    drawChart("chart-frequency", "t [s]", "ω [" + unit + "]", ev.t, freq);
    document.getElementById("chart-frequency").dataset.unit = unit;
    const used = document.getElementById("method-used");
    used.textContent = result.method_used
      ? "Method: " + result.method + " → " + result.method_used
        + (result.method_reason ? " (" + result.method_reason + ")" : "")
      : result.method ? "Method: " + result.method : "";
    // a run that grows while every traced branch decays: the growing branch is not traced
    const note = document.getElementById("damping-note");
    const traced = ev.modes.some((m) => m.least_stable || m.sigma.some((v) => v > 0));
    note.hidden = !(instability(result).unstable && !traced);
    SF.showWarnings(document.getElementById("warnings"), result.warnings);
  }

  // ---- the mode shapes, animated (a GIF drawn by the API: pipeflow.io.animation) -------

  function modeShapes(key) {
    const box = document.getElementById("mode-shapes");
    const block = state.result && state.result.mode_shapes;
    box.hidden = !(block && block.modes && block.modes.length);
    if (box.hidden) return;
    const modeSel = document.getElementById("shape-mode");
    const timeSel = document.getElementById("shape-time");
    modeSel.textContent = "";
    for (const m of block.modes) {
      modeSel.append(el("option", { value: String(m.mode) }, "mode " + m.mode));
    }
    timeSel.textContent = "";
    block.t.forEach((t, i) => timeSel.append(el("option", { value: String(i) }, "t = " + tick(t) + " s")));
    const show = () => {
      const img = document.getElementById("shape-gif");
      img.src = API.result(key) + "/animations/mode_shapes.gif?mode=" + modeSel.value
        + "&time_index=" + timeSel.value;
      img.alt = "mode " + modeSel.value + " in motion";
    };
    modeSel.onchange = show;
    timeSel.onchange = show;
    show();
  }

  function el(tag, attrs, text) {
    const node = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) node.setAttribute(k, v);
    if (text !== undefined) node.textContent = text;
    return node;
  }

  function share(key, spec) {
    modeShapes(key);
    SF.shareLink(document.getElementById("share-link"), { key, spec });
    document.getElementById("csv-history").href = API.result(key) + "?format=csv";
    document.getElementById("csv-eigen").href = API.result(key) + "?format=csv&table=eigenvalues";
    P.reportLinks(key);
  }

  // ---- API calls -------------------------------------------------------------------------

  async function run(event) {
    if (event) event.preventDefault();
    SF.clearErrors(form);
    const spec = specFromForm();
    runButton.disabled = true;
    statusEl.textContent = "running…";
    const started = performance.now();
    try {
      const answer = await SF.post(API.simulate, spec, form, formError);
      if (!answer.ok) { statusEl.textContent = answer.title; return; }
      const result = answer.body;
      state.key = result.key;
      render(result);
      share(result.key, spec);
      P.reveal();
      const seconds = ((performance.now() - started) / 1000).toFixed(2);
      statusEl.textContent = "done (" + result.status + ", " + (result.cached ? "cached" : "computed")
        + " in " + seconds + " s)";
    } catch (e) {
      statusEl.textContent = "network error: " + e.message;
    } finally {
      runButton.disabled = false;
    }
  }

  async function start() {
    const doc = await (await fetch("openapi.json")).json();
    state.doc = doc;
    state.schema = SF.requestSchema(doc, "/v1/simulations").schema;
    // the frequency axis's units: those the API's figures offer (that this page converts)
    const units = document.getElementById("frequency-unit");
    for (const u of P.plotUnits(doc).frequency) if (u in PER_RAD_S) units.add(new Option(u, u));
    const link = page.link();
    // a new load: a point force at the tip (x = pipe.L as typed, in its unit), harmonic,
    // to be filled in
    SF.onNewItem("loads", (current) => {
      if (current.length) return current[current.length - 1];
      const L = SF.quantityOf(form.querySelector("input[name='pipe.L']"));
      return { kind: "point_force", position: typeof L === "string" ? undefined : L, force: { kind: "harmonic" } };
    });
    SF.render(host, doc, state.schema, link.spec || initialValues(state.schema));
    runButton.disabled = false;
    if (!link.key) return;
    await page.open(link.key, (result) => {
      state.key = result.key;
      render(result);
      share(result.key, link.spec);
    });
  }

  form.addEventListener("submit", run);
  document.querySelector("#short-run button").addEventListener("click", () => {
    // the suggested t_end in its field (in s), then a new run
    const input = form.querySelector("input[name='time.t_end']");
    input.value = document.getElementById("short-run").dataset.suggestedTEnd;
    input.dispatchEvent(new Event("input"));
    form.requestSubmit();
  });
  for (const id of ["tip-scale", "frequency-unit"]) {
    document.getElementById(id).addEventListener("change", () => {
      if (state.result) render(state.result);
    });
  }
  window.pipeflowViewer.ready = start().catch((e) => { statusEl.textContent = String(e); });
})();
