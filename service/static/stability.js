// pipeflow stability page: every analysis of POST /v1/stability and POST /v1/sweeps with a
// form generated from the request schemas in /openapi.json (SchemaForm).  Sweeps run as
// jobs: progress is polled from GET /v1/jobs/{key} until the result is ready.  Results
// show a summary, a table of every crossing (stability boundary, sigma = 0 of a tracked
// branch, Campbell excitation lines) and the server's figures (pipeflow.io.plots, SVG).
"use strict";

(function () {
  const SF = window.SchemaForm;
  const form = document.getElementById("stability-form");
  const host = document.getElementById("fields");
  const select = document.getElementById("analysis");
  const runButton = document.getElementById("run");
  const progressEl = document.getElementById("progress");
  const statusEl = document.getElementById("job-status");
  const formError = document.getElementById("form-error");
  const POLL_MS = 250;
  const state = { doc: null, analyses: {}, analysis: null, key: null, result: null, history: [], run: 0 };
  window.pipeflowStability = { state };

  const fmt = (v, digits) => (v === null || v === undefined ? "—"
    : typeof v === "number" ? (Number.isInteger(v) ? String(v) : +v.toPrecision(digits || 6) + "")
      : String(v));

  // ---- analyses and their forms ---------------------------------------------------------

  function loadAnalyses(doc) {
    const stability = SF.requestSchema(doc, "/v1/stability");
    state.analyses.stability = {
      label: "critical velocities", schema: stability.schema, endpoint: "v1/stability", job: false,
      example: (stability.schema.examples || [])[0], description: stability.schema.description,
    };
    const sweeps = SF.requestSchema(doc, "/v1/sweeps");
    const disc = sweeps.schema.discriminator;
    for (const [kind, ref] of Object.entries(disc.mapping)) {
      const schema = SF.deref(doc, { $ref: ref });
      state.analyses[kind] = {
        label: kind.replace(/_/g, " "), schema, endpoint: "v1/sweeps", job: true,
        discriminator: disc.propertyName,
        example: (sweeps.examples[kind] || {}).value, description: schema.description,
      };
    }
    select.textContent = "";
    for (const [name, a] of Object.entries(state.analyses)) select.add(new Option(a.label, name));
  }

  function showForm(name, values) {
    const a = state.analyses[name];
    state.analysis = name;
    select.value = name;
    document.getElementById("analysis-help").textContent = a.description || "";
    SF.render(host, state.doc, a.schema, values || a.example || {});
  }

  function specFromForm() {
    const a = state.analyses[state.analysis];
    const spec = SF.collect(host, state.doc, a.schema);
    return a.job ? Object.assign({ [a.discriminator]: state.analysis }, spec) : spec;
  }

  // ---- results ---------------------------------------------------------------------------

  function table(title, columns, rows) {
    const wrap = document.createElement("div");
    const h = document.createElement("h2");
    h.textContent = title + " (" + rows.length + ")";
    const t = document.createElement("table");
    t.className = "data";
    const head = t.createTHead().insertRow();
    for (const [label] of columns) {
      const th = document.createElement("th");
      th.textContent = label;
      head.appendChild(th);
    }
    const body = t.createTBody();
    for (const r of rows) {
      const tr = body.insertRow();
      for (const [, get] of columns) tr.insertCell().textContent = fmt(get(r));
    }
    wrap.append(h, t);
    wrap.dataset.rows = String(rows.length);
    return wrap;
  }

  const VIEWS = {
    stability(r) {
      const cr = r.critical_velocity;
      const u = r.dimensionless && r.dimensionless.u_cr;
      return {
        summary: cr === null || cr === undefined
          ? (r.stable_throughout ? "Stable over the whole range." : "No loss of stability found in the range.")
          : "Critical velocity v_cr = " + fmt(cr) + " m/s (u_cr = " + fmt(u, 4) + ") at ω0 = " + fmt(r.omega0)
            + " rad/s; stable on " + (r.stable_intervals || []).map((i) => "[" + i.map((x) => fmt(x, 5)).join(", ") + "]").join(", ") + " m/s.",
        unstable: cr !== null && cr !== undefined,
        tables: [table("Every crossing of σ = 0", [
          ["velocity [m/s]", (c) => c.velocity], ["frequency [rad/s]", (c) => c.frequency],
          ["frequency [Hz]", (c) => c.frequency_hz], ["mode", (c) => c.mode], ["kind", (c) => c.kind],
          ["direction", (c) => c.direction], ["boundary", (c) => c.boundary], ["flow number u [-]", (c) => c.flow_number],
        ], r.crossings || [])],
      };
    },
    argand(r) {
      const zeros = r.zero_crossings || [];
      const loss = zeros.find((c) => c.direction === "loss");
      return {
        summary: loss ? "Critical point: mode " + loss.mode + " crosses σ = 0 at v = " + fmt(loss.value) + " m/s, ω = " + fmt(loss.frequency) + " rad/s."
          : "No tracked branch crosses σ = 0.",
        unstable: !!loss,
        tables: [table("Crossings of σ = 0 by the tracked branches", [
          ["velocity [m/s]", (c) => c.value], ["frequency [rad/s]", (c) => c.frequency],
          ["mode", (c) => c.mode], ["direction", (c) => c.direction],
        ], zeros)],
      };
    },
    campbell(r) {
      const exc = r.excitation || { orders: [], crossings: [] };
      const zeros = r.zero_crossings || [];
      const loss = zeros.find((c) => c.direction === "loss");
      return {
        summary: "Excitation orders " + exc.orders.map((n) => fmt(n) + "x").join(", ") + ": "
          + exc.crossings.length + " crossings with the tracked branches at v = " + fmt((r.fixed || {}).velocity) + " m/s."
          + (loss ? " Mode " + loss.mode + " loses stability at ω0 = " + fmt(loss.value) + " rad/s." : ""),
        unstable: zeros.some((c) => c.direction === "loss"),
        tables: [table("Crossings of the excitation lines ω = n ω0", [
          ["order n", (c) => c.order], ["mode", (c) => c.mode], ["spin [rad/s]", (c) => c.spin],
          ["spin [rpm]", (c) => c.spin_rpm], ["frequency [rad/s]", (c) => c.frequency],
          ["σ [1/s]", (c) => c.sigma], ["damping ratio ζ [-]", (c) => c.damping_ratio],
        ], exc.crossings), table("Crossings of σ = 0 by the tracked branches", [
          ["spin [rad/s]", (c) => c.value], ["frequency [rad/s]", (c) => c.frequency],
          ["mode", (c) => c.mode], ["direction", (c) => c.direction],
        ], zeros)],
      };
    },
    spin_map(r) {
      const rows = r.spins.map((w, i) => ({ w, rpm: r.spins_rpm[i], v: r.critical_velocity[i], n: (r.crossings[i] || []).length }));
      const found = rows.filter((x) => x.v !== null);
      return {
        summary: "Critical velocity at " + found.length + " of " + rows.length + " spins.",
        unstable: found.length > 0,
        tables: [table("Critical velocity per spin", [
          ["spin [rad/s]", (x) => x.w], ["spin [rpm]", (x) => x.rpm], ["v_cr [m/s]", (x) => x.v],
          ["boundary crossings", (x) => x.n],
        ], rows)],
      };
    },
    beta_map(r) {
      const rows = r.betas.map((b, i) => ({ b, u: r.u_cr[i], n: (r.crossings[i] || []).length }));
      return {
        summary: "u_cr(β) at γ = " + fmt(r.gamma) + "; " + (r.multiple_crossings || []).length
          + " mass ratios with more than one crossing (S-shaped segments).",
        unstable: rows.some((x) => x.u !== null),
        tables: [table("Critical flow number per mass ratio", [
          ["β [-]", (x) => x.b], ["u_cr [-]", (x) => x.u], ["crossings", (x) => x.n],
        ], rows)],
      };
    },
  };

  function genericView(r) {
    const scalars = Object.entries(r).filter(([k, v]) => v === null || typeof v !== "object")
      .filter(([k]) => !["key", "cached", "kind"].includes(k));
    return {
      summary: r.verdict !== undefined ? "Verdict: " + r.verdict + "." : r.kind + " result.",
      unstable: r.verdict === "unstable",
      tables: [table("Values", [["name", (x) => x[0]], ["value", (x) => x[1]]], scalars)],
    };
  }

  function render(result) {
    state.result = result;
    document.getElementById("results").hidden = false;
    const view = (VIEWS[result.kind] || genericView)(result);
    const summary = document.getElementById("summary");
    summary.textContent = view.summary;
    summary.classList.toggle("ok", !view.unstable);
    summary.dataset.kind = result.kind;
    const tables = document.getElementById("tables");
    tables.textContent = "";
    for (const t of view.tables) tables.appendChild(t);
    const plots = document.getElementById("plots");
    plots.textContent = "";
    for (const name of result.plots || []) {
      const fig = document.createElement("figure");
      const img = document.createElement("img");
      const base = "v1/results/" + encodeURIComponent(result.key) + "/plots/" + name;
      img.src = base + ".svg";
      img.alt = name;
      img.dataset.plot = name;
      const cap = document.createElement("figcaption");
      cap.innerHTML = "";
      const a = document.createElement("a");
      a.href = base + ".png";
      a.textContent = name + " (PNG)";
      cap.appendChild(a);
      fig.append(img, cap);
      plots.appendChild(fig);
    }
    SF.showWarnings(document.getElementById("warnings"), result.warnings);
  }

  function share(key, spec) {
    SF.shareLink(document.getElementById("share-link"), { analysis: state.analysis, key, spec });
    document.getElementById("json-link").href = "v1/results/" + encodeURIComponent(key);
  }

  // ---- API calls -------------------------------------------------------------------------

  function showJob(job) {
    state.history.push({ status: job.status, progress: job.progress });
    progressEl.hidden = false;
    progressEl.value = job.progress;
    statusEl.textContent = job.status + " " + Math.round(100 * job.progress) + " %";
  }

  async function fetchResult(key) {
    const response = await fetch("v1/results/" + encodeURIComponent(key), { headers: { Accept: "application/json" } });
    if (!response.ok) throw await SF.problemOf(response);
    return await response.json();
  }

  async function follow(job, run) {
    // poll the job until it is finished; a newer run stops this one
    for (;;) {
      if (run !== state.run) return null;
      showJob(job);
      if (job.status === "succeeded") return await fetchResult(job.key);
      if (job.status === "failed" || job.status === "cancelled") throw job.error || { title: "job " + job.status };
      await new Promise((r) => setTimeout(r, POLL_MS));
      const response = await fetch("v1/jobs/" + encodeURIComponent(job.key));
      if (!response.ok) throw await SF.problemOf(response);
      job = await response.json();
    }
  }

  async function run(event) {
    if (event) event.preventDefault();
    SF.clearErrors(form);
    const a = state.analyses[state.analysis];
    const spec = specFromForm();
    const token = ++state.run;
    state.history = [];
    runButton.disabled = true;
    statusEl.textContent = "submitting…";
    progressEl.hidden = !a.job;
    progressEl.value = 0;
    try {
      const answer = await SF.post(a.endpoint, spec, form, formError);
      if (!answer.ok) { statusEl.textContent = answer.title; return; }
      const result = a.job ? await follow(answer.body, token) : answer.body;
      if (!result) return;
      state.key = result.key;
      render(result);
      share(result.key, spec);
      statusEl.textContent = a.job ? "done (job " + result.key.slice(0, 12) + "…)"
        : "done (" + (result.cached ? "cached" : "computed") + ")";
    } catch (problem) {
      statusEl.textContent = problem && problem.title !== undefined
        ? SF.showProblem(form, problem, formError) : "error: " + String(problem && problem.message || problem);
    } finally {
      if (token === state.run) runButton.disabled = false;
    }
  }

  async function start() {
    state.doc = await (await fetch("openapi.json")).json();
    loadAnalyses(state.doc);
    const params = new URLSearchParams(window.location.search);
    const name = state.analyses[params.get("analysis")] ? params.get("analysis") : "stability";
    let spec = null;
    if (params.get("spec")) {
      try { spec = JSON.parse(params.get("spec")); } catch (e) { statusEl.textContent = "bad spec in link"; }
    }
    showForm(name, spec);
    runButton.disabled = false;
    const key = params.get("key");
    if (!key) return;
    statusEl.textContent = "loading " + key.slice(0, 12) + "…";
    try {
      const result = await fetchResult(key);
      state.key = key;
      render(result);
      share(key, spec);
      statusEl.textContent = "loaded result " + key.slice(0, 12) + "…";
    } catch (problem) {
      statusEl.textContent = SF.showProblem(form, problem, formError);
    }
  }

  form.addEventListener("submit", run);
  select.addEventListener("change", () => showForm(select.value));
  window.pipeflowStability.ready = start().catch((e) => { statusEl.textContent = String(e); });
})();
