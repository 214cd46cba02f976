// pipeflow frequency-response page: a form generated from the request schema of
// POST /v1/frequency-responses in /openapi.json (SchemaForm), one run on this service, and
// uPlot charts of the answer: |H| against frequency on log-log axes with the peaks marked
// (one curve per operating point and position), the phase [rad], a table of the peaks
// (frequency, damping ratio, |H|) and the server's figures (bode, nyquist, waterfall, ...).
// One operating point (flow.velocity, rotation.omega0) or several (operating_points, a list
// in the form): with operating points given, the single point's fields are greyed out and
// not sent (the API refuses both at once).  The request's named examples (hammer test,
// waterfall) can be loaded into the form.
"use strict";

(function () {
  const SF = window.SchemaForm;
  const P = window.PipeflowPages;
  const { fmt, tick, finite, positive } = P;
  const form = document.getElementById("frf-form");
  const host = document.getElementById("fields");
  const runButton = document.getElementById("run");
  const statusEl = document.getElementById("status");
  const formError = document.getElementById("form-error");
  const ENDPOINT = "v1/frequency-responses";
  const COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"];
  const state = { doc: null, schema: null, example: null, result: null, charts: {}, run: 0 };
  window.pipeflowFrequency = { state };

  const page = P.page({ form, formError, status: statusEl, button: runButton, state, progress: null });

  // ---- the curves of a result -------------------------------------------------------------

  function curves(r) {
    // one curve per operating point and position, labelled only by what varies
    const out = [];
    const many = r.operating_points.length > 1;
    r.operating_points.forEach((p, i) => {
      p.responses.forEach((c, j) => {
        const parts = [];
        if (many) parts.push("v = " + fmt(p.velocity) + " m/s, ω0 = " + fmt(p.omega0) + " rad/s");
        if (r.positions.length > 1 || !many) parts.push("x = " + fmt(c.position) + " m");
        out.push({ label: parts.join(", "), point: p, pointIndex: i, positionIndex: j, curve: c });
      });
    });
    return out;
  }

  function peakSeries(r, k) {
    // |H| at the peaks of curve k, null elsewhere: the peaks drawn as markers
    const W = r.frequencies;
    const y = W.map(() => null);
    const H = k.curve.magnitude;
    for (const p of k.point.peaks) {
      let best = 0;
      for (let i = 1; i < W.length; i++) if (Math.abs(W[i] - p.frequency) < Math.abs(W[best] - p.frequency)) best = i;
      // an undamped peak's |H| is infinite (null): marked at the curve's nearest value
      const m = p.magnitude[k.positionIndex];
      const at = typeof m === "number" && Number.isFinite(m) && m > 0 ? m : H[best];
      if (typeof at === "number" && Number.isFinite(at) && at > 0) y[best] = at;
    }
    return y;
  }

  function chart(id, yLabel, series, logY) {
    const chartHost = document.getElementById(id);
    // a log axis needs a positive value to span: |H| = 0 everywhere (or all missing) is
    // drawn on a linear axis instead of an empty log one
    if (logY && !series.some((s) => s.y.some((v) => v !== null && v > 0))) logY = false;
    chartHost.dataset.scale = logY ? "log" : "linear";
    if (state.charts[id]) { state.charts[id].destroy(); delete state.charts[id]; }
    const r = state.result;
    const width = P.chartWidth(chartHost, 900);
    const plot = new uPlot({
      width, height: 280,
      scales: { x: { time: false, distr: 3 }, y: logY ? { distr: 3 } : { auto: true } },
      axes: [{ label: "frequency Ω [rad/s]", values: (u, s) => s.map(tick) },
        { label: yLabel, size: 80, values: (u, s) => s.map(tick) }],
      series: [{ label: "Ω [rad/s]" }].concat(series.map((s) => s.opts)),
      cursor: { drag: { x: true, y: false } },
    }, [r.frequencies.map((w) => (w > 0 ? w : null))].concat(series.map((s) => s.y)), chartHost);
    state.charts[id] = plot;
    chartHost.dataset.points = String(r.frequencies.length);
    chartHost.dataset.series = String(series.length);
  }

  function draw(r) {
    const ks = curves(r);
    const mag = [];
    const phase = [];
    let markers = 0;
    ks.forEach((k, i) => {
      const color = COLORS[i % COLORS.length];
      mag.push({ y: positive(k.curve.magnitude), opts: { label: k.label || "|H|", stroke: color, width: 1.3 } });
      const peaks = peakSeries(r, k);
      markers += peaks.filter((v) => v !== null).length;
      mag.push({
        y: peaks,
        opts: { label: "peaks", stroke: color, width: 0, paths: () => null, points: { show: true, size: 9, fill: color } },
      });
      phase.push({ y: finite(k.curve.phase), opts: { label: k.label || "arg H", stroke: color, width: 1.1 } });
    });
    document.getElementById("magnitude-title").textContent = "Magnitude |H| [" + r.unit + "] (" + r.quantity + " per unit load; ● peaks)";
    chart("chart-magnitude", "|H| [" + r.unit + "]", mag, true);
    chart("chart-phase", "arg H [rad]", phase, false);
    document.getElementById("chart-magnitude").dataset.peaks = String(markers);
  }

  // ---- tables, summary, figures ----------------------------------------------------------

  function render(r) {
    state.result = r;
    document.getElementById("results").hidden = false;
    const summary = document.getElementById("summary");
    const unstable = r.operating_points.filter((p) => !p.stable);
    const n = r.operating_points.reduce((s, p) => s + p.peaks.length, 0);
    summary.textContent = unstable.length
      ? "Unstable: " + unstable.length + " of " + r.operating_points.length + " operating points grow (largest growth rate "
        + fmt(r.max_growth_rate, 4) + " 1/s); there is no steady state and H is formal there."
      : "Stable at every operating point: " + n + " peaks in " + fmt(r.frequencies[0]) + " … "
        + fmt(r.frequencies[r.frequencies.length - 1]) + " rad/s (" + r.frequencies.length + " frequencies).";
    summary.classList.toggle("ok", unstable.length === 0);
    const rows = [];
    for (const p of r.operating_points) for (const k of p.peaks) rows.push(Object.assign({ point: p }, k));
    const columns = [["v [m/s]", (x) => x.point.velocity], ["ω0 [rad/s]", (x) => x.point.omega0],
      ["mode", (x) => x.mode], ["frequency [rad/s]", (x) => x.frequency],
      ["natural frequency [rad/s]", (x) => x.natural_frequency], ["damping ratio ζ [-]", (x) => x.damping_ratio]];
    // an undamped peak (ζ = 0) has no finite |H|: the answer's null is shown as ∞
    const peakMagnitude = (k, j) => (k.magnitude[j] === null && k.damping_ratio === 0 ? "∞ (undamped)" : k.magnitude[j]);
    r.positions.forEach((x, j) => columns.push(["|H(x = " + fmt(x) + " m)| [" + r.unit + "]", (k) => peakMagnitude(k, j)]));
    const tables = document.getElementById("tables");
    tables.textContent = "";
    tables.appendChild(P.columnTable("Peaks", columns, rows));
    draw(r);
    P.figures(document.getElementById("plots"), r.key, r.plots);
    SF.showWarnings(document.getElementById("warnings"), r.warnings);
  }

  function share(key, spec) {
    SF.shareLink(document.getElementById("share-link"), { key, spec });
    const base = P.resultUrl(key);
    document.getElementById("json-link").href = base;
    document.getElementById("csv-frf").href = base + "?format=csv&table=frequency_response";
    document.getElementById("csv-peaks").href = base + "?format=csv&table=peaks";
  }

  // ---- one operating point or several ------------------------------------------------------

  // the single point's fields (a constant profile: a group, or a kind union)
  const SINGLE = ["[data-group='flow']", "[data-group='rotation.omega0'], [data-union='rotation.omega0']"];

  function pointsCount() {
    const list = host.querySelector("[data-list='operating_points']");
    return list ? Number(list.dataset.count || 0) : 0;
  }

  function syncMode() {
    // with operating points, flow.velocity and rotation.omega0 are not used: greyed out
    const several = pointsCount() > 0;
    for (const sel of SINGLE) {
      const box = host.querySelector(sel);
      if (!box) continue;
      box.classList.toggle("superseded", several);
      for (const input of box.querySelectorAll("input, select")) input.disabled = several;
      let note = box.querySelector(":scope > .superseded-note");
      if (several && !note) {
        note = document.createElement("p");
        note.className = "superseded-note";
        note.textContent = "not used: the operating points below give v and ω0";
        box.appendChild(note);
      } else if (!several && note) {
        note.remove();
      }
    }
    form.dataset.mode = several ? "operating_points" : "single";
  }

  function specFromForm() {
    const spec = SF.collect(host, state.doc, state.schema);
    if (spec.operating_points) {
      // the API answers 422 to both forms at once: the list wins (hub_radius still applies)
      delete spec.flow;
      if (spec.rotation) {
        delete spec.rotation.omega0;
        if (!Object.keys(spec.rotation).length) delete spec.rotation;
      }
    }
    return spec;
  }

  function newPoint(current) {
    // the first operating point: the single point's v and ω0 as typed; then a copy of the last
    if (current.length) return current[current.length - 1];
    const num = (name) => {
      // the number as typed, with its unit (rpm: {"value", "unit"}); nothing if not a number
      const v = SF.quantityOf(host.querySelector("input[name='" + name + "']"));
      return typeof v === "string" ? undefined : v;
    };
    return { velocity: num("flow.velocity.value"), omega0: num("rotation.omega0.value") };
  }

  function fillForm(values) {
    SF.render(host, state.doc, state.schema, values);
    syncMode();
  }

  // ---- API calls -------------------------------------------------------------------------

  function show(result, spec) {
    render(result);
    share(result.key, spec);
  }

  function run(event) {
    if (event) event.preventDefault();
    return page.run({ endpoint: ENDPOINT, spec: specFromForm, job: false, busy: "computing…", show });
  }

  async function start() {
    state.doc = await (await fetch("openapi.json")).json();
    const req = SF.requestSchema(state.doc, "/" + ENDPOINT);
    state.schema = req.schema;
    state.example = (req.examples.hammer || {}).value || (req.schema.examples || [])[0] || {};
    const link = page.link();
    SF.onNewItem("operating_points", newPoint);
    P.examplesChooser(document.getElementById("example"), req.examples,
      link.spec ? "" : req.examples.hammer ? "hammer" : "", fillForm);
    fillForm(link.spec || state.example);
    runButton.disabled = false;
    if (link.key) await page.open(link.key, (result) => show(result, link.spec));
  }

  form.addEventListener("submit", run);
  form.addEventListener("listchange", syncMode);
  window.pipeflowFrequency.ready = start().catch((e) => { statusEl.textContent = String(e); });
})();
