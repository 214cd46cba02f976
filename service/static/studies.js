// pipeflow design-study page: a form generated from the request schema of POST /v1/studies
// in /openapi.json (SchemaForm: the base request with its kind, and cases, a grid or sampled
// parameters as list and map editors), the API's examples plus two sampled studies of the
// README, the job followed through GET /v1/jobs/{key} until its result is ready, or a study
// opened by key (?key=..., a shareable link, or the key box; a study still running is
// followed too), its form then filled with the study's own request (the result echoes it).
// The result: a banner with the counts and the probability that a case is unstable (with its
// binomial standard error), for saltelli designs the Sobol' indices S1 and ST of each summary
// column per parameter (bars with their confidence intervals as whiskers), a histogram of
// each numeric summary column over the ok cases with the mean and the 5/50/95 % quantiles
// marked, the statistics table and the first rows of the study's table with links to the
// whole table as CSV and Parquet (the export endpoints).  Units are the columns' own.
"use strict";

(function () {
  const SF = window.SchemaForm;
  const P = window.PipeflowPages;
  const { fmt, table } = P;
  const form = document.getElementById("study-form");
  const host = document.getElementById("fields");
  const runButton = document.getElementById("run");
  const progressEl = document.getElementById("progress");
  const statusEl = document.getElementById("job-status");
  const formError = document.getElementById("form-error");
  const ENDPOINT = "v1/studies";
  //: rows of the study's table shown on the page (the whole table: CSV / Parquet)
  const ROWS_SHOWN = 20;
  const BAR = "#4c78a8";
  const MARKERS = [
    { name: "mean", color: "#d62728", dash: [] },
    { name: "0.05", label: "5 %", color: "#2ca02c", dash: [6, 4] },
    { name: "0.5", label: "50 %", color: "#111111", dash: [2, 3] },
    { name: "0.95", label: "95 %", color: "#2ca02c", dash: [6, 4] },
  ];
  const INDEX_COLORS = { S1: "#4c78a8", ST: "#f58518" };
  const state = { doc: null, schema: null, key: null, result: null, history: [], charts: {}, run: 0 };
  window.pipeflowStudies = { state };

  const page = P.page({ form, formError, status: statusEl, button: runButton, state, progress: progressEl });
  // axis ticks with two decimals in the exponent form (1.25e5, 2e-3)
  const tick = P.tickFormat(2);

  const withUnit = (name, unit) => (unit ? name + " [" + unit + "]" : name);

  // ---- examples: the API's, and two sampled studies (README "Uncertainty") -------------------

  const PAPER_PIPE = { E: 7.8e9, I: 1.21e-17, L: 0.025, M1: 1.884e-5, M2: 1.6485e-5 };
  const UNCERTAIN = {
    "pipe.E": { distribution: "lognormal", median: 7.8e9, sigma: 0.05 },
    "pipe.M2": { distribution: "uniform", low: 1.5e-5, high: 1.8e-5 },
  };
  const STABILITY_BASE = {
    kind: "stability",
    spec: {
      pipe: PAPER_PIPE, rotation: { omega0: { kind: "constant", value: 100.0 } },
      modes: 6, points: 61, velocity_range: [0.0, 40.0],
    },
  };
  const PAGE_EXAMPLES = {
    monte_carlo: {
      summary: "Critical velocity with uncertain E and M2: 64 Sobol' points, P(unstable at 27 m/s)",
      value: {
        base: STABILITY_BASE, operating_velocity: 27.0,
        samples: { count: 64, method: "sobol", seed: 1, parameters: UNCERTAIN },
      },
    },
    sensitivity: {
      summary: "Sobol' indices of the critical velocity: 32 base points (192 cases, saltelli)",
      value: {
        base: STABILITY_BASE,
        samples: { count: 32, method: "saltelli", seed: 1, parameters: UNCERTAIN },
      },
    },
  };

  // ---- charts ----------------------------------------------------------------------------

  function chartHost(parent, id, title) {
    const box = document.createElement("div");
    box.className = "chart";
    box.id = id;
    const h = document.createElement("h2");
    h.textContent = title;
    box.appendChild(h);
    parent.appendChild(box);
    return box;
  }

  function legend(box, items) {
    // a fixed legend under a chart: what each colour marks, with its value
    const p = document.createElement("p");
    p.className = "chart-legend";
    for (const it of items) {
      const span = document.createElement("span");
      span.className = "item";
      span.dataset.marker = it.name;
      const swatch = document.createElement("span");
      swatch.className = "swatch" + (it.dashed ? " dashed" : "") + (it.block ? " block" : "");
      swatch.style.borderColor = it.color;
      if (it.block) swatch.style.background = it.color;
      span.append(swatch, it.text);
      p.appendChild(span);
    }
    box.appendChild(p);
  }

  function bins(values) {
    // equal-width bins over [min, max]: about sqrt(n) of them (5..40); one bin if all equal
    const lo = Math.min(...values);
    const hi = Math.max(...values);
    if (!(hi > lo)) {
      const half = lo === 0 ? 0.5 : Math.abs(lo) * 0.01;
      return { edges: [lo - half, lo + half], counts: [values.length] };
    }
    const n = Math.max(5, Math.min(40, Math.ceil(Math.sqrt(values.length))));
    const width = (hi - lo) / n;
    const edges = Array.from({ length: n + 1 }, (_, i) => lo + i * width);
    edges[n] = hi;
    const counts = new Array(n).fill(0);
    for (const v of values) counts[Math.min(n - 1, Math.floor((v - lo) / width))] += 1;
    return { edges, counts };
  }

  function clipped(u, draw) {
    const ctx = u.ctx;
    ctx.save();
    ctx.beginPath();
    ctx.rect(u.bbox.left, u.bbox.top, u.bbox.width, u.bbox.height);
    ctx.clip();
    draw(ctx);
    ctx.restore();
  }

  function histogram(parent, name, unit, values, stats) {
    const id = "hist-" + name.replace(/[^A-Za-z0-9_-]/g, "_");
    const box = chartHost(parent, id, "Histogram of " + withUnit(name, unit) + " over " + values.length + " ok cases");
    box.dataset.column = name;
    box.classList.add("histogram");
    const { edges, counts } = bins(values);
    const centres = counts.map((_, i) => (edges[i] + edges[i + 1]) / 2);
    const marks = MARKERS.map((m) => ({ ...m, x: m.name === "mean" ? stats.mean : (stats.quantiles || {})[m.name] }))
      .filter((m) => typeof m.x === "number" && Number.isFinite(m.x));
    const span = edges[edges.length - 1] - edges[0];
    const xmin = Math.min(edges[0], ...marks.map((m) => m.x)) - 0.03 * span;
    const xmax = Math.max(edges[edges.length - 1], ...marks.map((m) => m.x)) + 0.03 * span;
    // two histograms a row on a wide page
    const width = Math.max(320, Math.min(520, Math.floor((parent.clientWidth || 1060) / 2) - 16));
    const plot = new uPlot({
      width, height: 240,
      scales: { x: { time: false, range: [xmin, xmax] }, y: { range: (u, lo, hi) => [0, Math.max(1, hi) * 1.08] } },
      axes: [{ label: withUnit(name, unit), values: (u, s) => s.map(tick) },
        { label: "cases [-]", size: 60, values: (u, s) => s.map((v) => (Number.isInteger(v) ? String(v) : "")) }],
      series: [{ label: withUnit(name, unit), value: (u, v) => tick(v) },
        { label: "cases in bin", stroke: BAR, fill: BAR, width: 0, paths: () => null, points: { show: false } }],
      cursor: { drag: { x: true, y: false } },
      hooks: {
        draw: [(u) => clipped(u, (ctx) => {
          // the bars: one rectangle per bin from its left to its right edge
          const y0 = u.valToPos(0, "y", true);
          ctx.fillStyle = "rgba(76, 120, 168, 0.75)";
          ctx.strokeStyle = "#ffffff";
          ctx.lineWidth = 1;
          counts.forEach((c, i) => {
            if (!c) return;
            const x0 = u.valToPos(edges[i], "x", true);
            const x1 = u.valToPos(edges[i + 1], "x", true);
            const y1 = u.valToPos(c, "y", true);
            ctx.fillRect(x0, y1, x1 - x0, y0 - y1);
            ctx.strokeRect(x0, y1, x1 - x0, y0 - y1);
          });
          // the mean and the quantiles: vertical lines across the plot
          ctx.lineWidth = 2 * (window.devicePixelRatio || 1);
          for (const m of marks) {
            const x = u.valToPos(m.x, "x", true);
            ctx.strokeStyle = m.color;
            ctx.setLineDash(m.dash.map((d) => d * (window.devicePixelRatio || 1)));
            ctx.beginPath();
            ctx.moveTo(x, u.bbox.top);
            ctx.lineTo(x, u.bbox.top + u.bbox.height);
            ctx.stroke();
          }
          ctx.setLineDash([]);
        })],
      },
    }, [centres, counts], box);
    state.charts[id] = plot;
    box.style.width = width + "px";
    box.dataset.bins = String(counts.length);
    box.dataset.count = String(values.length);
    box.dataset.markers = String(marks.length);
    legend(box, [{ name: "bins", color: BAR, block: true, text: counts.length > 1 ? "cases per bin (" + counts.length + " bins)"
      : "all " + values.length + " values equal" }].concat(marks.map((m) => ({
      name: m.name, color: m.color, dashed: m.dash.length > 0,
      text: (m.label || m.name) + " = " + fmt(m.x, 4) + (unit && unit !== "-" ? " " + unit : ""),
    }))));
  }

  function sensitivityChart(parent, name, unit, column, conf) {
    // S1 and ST per parameter as grouped vertical bars, the confidence half-widths as whiskers
    const id = "sobol-" + name.replace(/[^A-Za-z0-9_-]/g, "_");
    const box = chartHost(parent, id, "Sobol' indices of " + withUnit(name, unit) + " (whiskers: " + Math.round(100 * conf) + " % confidence)");
    box.dataset.column = name;
    box.classList.add("sensitivity");
    const params = Object.keys(column.parameters);
    const ix = params.map((p) => column.parameters[p]);
    const xs = params.map((_, i) => i);
    const S1 = ix.map((v) => v.S1);
    const ST = ix.map((v) => v.ST);
    const ends = ix.flatMap((v) => [v.S1 - v.S1_conf, v.S1 + v.S1_conf, v.ST - v.ST_conf, v.ST + v.ST_conf]);
    const ylo = Math.min(0, ...ends);
    const yhi = Math.max(1, ...ends);
    const width = Math.max(320, Math.min(520, 180 * params.length + 160));
    const dpr = window.devicePixelRatio || 1;
    const plot = new uPlot({
      width, height: 260,
      scales: { x: { time: false, range: [-0.5, params.length - 0.5] }, y: { range: [ylo - 0.05, yhi + 0.05] } },
      axes: [{ label: "parameter", splits: () => xs, values: (u, s) => s.map((v) => params[v] || ""), grid: { show: false } },
        { label: "Sobol' index [-]", size: 60, values: (u, s) => s.map(tick) }],
      series: [{ label: "parameter", value: (u, v) => (v === null ? "" : params[Math.round(v)] || "") },
        { label: "S1", stroke: INDEX_COLORS.S1, fill: INDEX_COLORS.S1, paths: () => null, points: { show: false }, value: (u, v) => fmt(v, 3) },
        { label: "ST", stroke: INDEX_COLORS.ST, fill: INDEX_COLORS.ST, paths: () => null, points: { show: false }, value: (u, v) => fmt(v, 3) }],
      cursor: { drag: { x: false, y: false } },
      hooks: {
        draw: [(u) => clipped(u, (ctx) => {
          const y0 = u.valToPos(0, "y", true);
          const slot = u.valToPos(1, "x", true) - u.valToPos(0, "x", true);
          const bw = slot * 0.3;
          // zero line
          ctx.strokeStyle = "#888";
          ctx.lineWidth = dpr;
          ctx.beginPath();
          ctx.moveTo(u.bbox.left, y0);
          ctx.lineTo(u.bbox.left + u.bbox.width, y0);
          ctx.stroke();
          ix.forEach((v, i) => {
            const xc = u.valToPos(i, "x", true);
            [["S1", v.S1, v.S1_conf, xc - bw], ["ST", v.ST, v.ST_conf, xc]].forEach(([key, val, half, left]) => {
              const y = u.valToPos(val, "y", true);
              ctx.fillStyle = INDEX_COLORS[key];
              ctx.fillRect(left + 0.05 * bw, Math.min(y, y0), 0.9 * bw, Math.abs(y0 - y));
              // the whisker: val - half .. val + half, with caps
              const a = u.valToPos(val - half, "y", true);
              const b = u.valToPos(val + half, "y", true);
              const mid = left + bw / 2;
              ctx.strokeStyle = "#222";
              ctx.lineWidth = 1.5 * dpr;
              ctx.beginPath();
              ctx.moveTo(mid, a); ctx.lineTo(mid, b);
              ctx.moveTo(mid - bw / 5, a); ctx.lineTo(mid + bw / 5, a);
              ctx.moveTo(mid - bw / 5, b); ctx.lineTo(mid + bw / 5, b);
              ctx.stroke();
            });
          });
        })],
      },
    }, [xs, S1, ST], box);
    state.charts[id] = plot;
    box.style.width = width + "px";
    box.dataset.parameters = String(params.length);
    box.dataset.bars = String(2 * params.length);
    legend(box, params.flatMap((p, i) => [
      { name: "S1:" + p, color: INDEX_COLORS.S1, block: true, text: p + ": S1 = " + fmt(ix[i].S1, 3) + " ± " + fmt(ix[i].S1_conf, 2) },
      { name: "ST:" + p, color: INDEX_COLORS.ST, block: true, text: "ST = " + fmt(ix[i].ST, 3) + " ± " + fmt(ix[i].ST_conf, 2) },
    ]));
  }

  // ---- the result ------------------------------------------------------------------------

  function unitOf(r, name) {
    const c = r.columns.find((x) => x.name === name);
    return c ? c.unit : "";
  }

  function summaryLines(r) {
    // [headline, detail]: the counts and the probability of instability, then its criterion
    const c = r.counts;
    const counts = r.counts.total + " cases of " + r.base_kind + ": " + c.ok + " ok, " + c.failed + " failed ("
      + c.cached + " from the cache, " + c.computed + " computed).";
    const p = r.statistics.instability;
    if (p && p.probability !== null) {
      return [counts + " P(unstable) = " + fmt(p.probability, 3) + " ± " + fmt(p.standard_error, 2)
        + " (standard error; " + p.unstable + " of " + p.decided + " decided cases unstable).",
      "Unstable: " + p.criterion];
    }
    if (p) return [counts + " P(unstable): no case decided.", "Unstable: " + p.criterion];
    return [counts, "P(unstable): give operating_velocity to count unstable cases of a stability base."];
  }

  function render(r) {
    state.result = r;
    for (const plot of Object.values(state.charts)) plot.destroy();
    state.charts = {};
    document.getElementById("results").hidden = false;
    const summary = document.getElementById("summary");
    const [headline, detail] = summaryLines(r);
    summary.textContent = "";
    const small = document.createElement("small");
    small.className = "detail";
    small.textContent = detail;
    summary.append(headline, small);
    const p = r.statistics.instability;
    summary.classList.toggle("ok", !p || !p.probability);
    summary.dataset.probability = p && p.probability !== null ? String(p.probability) : "";

    // the Sobol' indices (saltelli designs)
    const sens = document.getElementById("sensitivity");
    sens.textContent = "";
    if (r.sensitivity) {
      const h = document.createElement("h2");
      h.textContent = "Sensitivity: Sobol' indices (" + r.sensitivity.base_points + " base points)";
      sens.appendChild(h);
      for (const [name, col] of Object.entries(r.sensitivity.columns)) {
        if (col.available && col.parameters) {
          sensitivityChart(sens, name, unitOf(r, name), col, r.sensitivity.conf_level);
        } else {
          const note = document.createElement("p");
          note.className = "note";
          note.dataset.column = name;
          note.textContent = name + ": no indices (" + (col.reason || "not available") + ")";
          sens.appendChild(note);
        }
      }
    }

    // a histogram per numeric summary column, over the ok cases with a value
    const hists = document.getElementById("histograms");
    hists.textContent = "";
    const status = r.columns.findIndex((c) => c.name === "status");
    for (const [name, stats] of Object.entries(r.statistics.columns)) {
      const j = r.columns.findIndex((c) => c.name === name);
      const values = r.rows.filter((row) => status < 0 || row[status] === "ok").map((row) => row[j])
        .filter((v) => typeof v === "number" && Number.isFinite(v));
      if (j < 0 || !values.length) continue;
      histogram(hists, name, unitOf(r, name) || stats.unit, values, stats);
    }

    // the statistics and the first rows
    const tables = document.getElementById("tables");
    tables.textContent = "";
    const statRows = Object.entries(r.statistics.columns).map(([name, s]) => [
      withUnit(name, s.unit), s.count, s.mean, s.std, s.min, s.quantiles["0.05"], s.quantiles["0.5"], s.quantiles["0.95"], s.max]);
    const stats = table("Statistics over the " + r.statistics.ok + " ok cases",
      ["column", "count", "mean", "std", "min", "5 %", "50 %", "95 %", "max"], statRows);
    stats.id = "statistics";
    tables.appendChild(stats);
    const shown = r.rows.slice(0, ROWS_SHOWN);
    const cases = table("Cases (first " + shown.length + " of " + r.rows.length + ")",
      r.columns.map((c) => withUnit(c.name, c.unit && c.unit !== "" ? c.unit : null)),
      shown.map((row) => row.map((v, i) => (r.columns[i].name === "key" && typeof v === "string" ? v.slice(0, 12) + "…" : v))),
      r.rows.length > shown.length ? "The whole table: CSV or Parquet (links above)." : null);
    cases.id = "cases";
    tables.appendChild(cases);
    SF.showWarnings(document.getElementById("warnings"), r.warnings);
  }

  function share(key, spec) {
    SF.shareLink(document.getElementById("share-link"), { key, spec });
    const base = P.resultUrl(key);
    document.getElementById("json-link").href = base;
    document.getElementById("csv-link").href = base + "?format=csv&table=study";
    document.getElementById("parquet-link").href = base + "?format=parquet&table=study";
    document.getElementById("open-key").value = key;
    P.reportLinks(key);
  }

  // ---- API calls -------------------------------------------------------------------------

  function show(result, spec) {
    state.key = result.key;
    render(result);
    share(result.key, spec || result.request || null);
  }

  function fillFromResult(result, spec) {
    // a study opened by key without its request (the key box, a ?key= link): the form
    // shows the study's own request, which the result echoes (its normal form)
    if (spec || !result.request) return;
    SF.render(host, state.doc, state.schema, JSON.parse(JSON.stringify(result.request)));
    document.getElementById("example").value = "";
  }

  function run(event) {
    if (event) event.preventDefault();
    const spec = () => SF.collect(host, state.doc, state.schema);
    return page.run({ endpoint: ENDPOINT, spec, job: true, busy: "submitting…", show });
  }

  function open(key, spec) {
    // a study by key: its job followed while it runs (a stored result has no job: loaded)
    return page.open(key, (result) => {
      fillFromResult(result, spec);
      show(result, spec);
    }, true);
  }

  async function start() {
    state.doc = await (await fetch("openapi.json")).json();
    const req = SF.requestSchema(state.doc, "/" + ENDPOINT);
    state.schema = req.schema;
    const examples = Object.assign({}, req.examples, PAGE_EXAMPLES);
    const link = page.link();
    const first = Object.keys(req.examples)[0] || "monte_carlo";
    const fill = (values) => SF.render(host, state.doc, state.schema, values);
    P.examplesChooser(document.getElementById("example"), examples, link.spec ? "" : first, fill,
      (name) => (PAGE_EXAMPLES[name] ? " (this page)" : ""));
    fill(link.spec || JSON.parse(JSON.stringify(examples[first].value)));
    runButton.disabled = false;
    const keyInput = document.getElementById("open-key");
    document.getElementById("open").addEventListener("click", () => {
      const key = keyInput.value.trim();
      if (key) open(key, null);
    });
    if (link.key) await open(link.key, link.spec);
  }

  form.addEventListener("submit", run);
  window.pipeflowStudies.ready = start().catch((e) => { statusEl.textContent = String(e); });
})();
