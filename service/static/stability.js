// pipeflow stability page: every analysis of POST /v1/stability and POST /v1/sweeps with a
// form generated from the request schemas in /openapi.json (SchemaForm).  Sweeps run as
// jobs: progress is polled from GET /v1/jobs/{key} until the result is ready.  Results
// show a summary, a table of every crossing (stability boundary, sigma = 0 of a tracked
// branch, Campbell excitation lines) and the server's figures (pipeflow.io.plots, SVG), their
// spin and frequency axes in the units chosen (rad/s, rpm, Hz), and links to the result's
// report (HTML, PDF).
"use strict";

(function () {
  const SF = window.SchemaForm;
  const P = window.PipeflowPages;
  const { fmt } = P;
  const form = document.getElementById("stability-form");
  const host = document.getElementById("fields");
  const select = document.getElementById("analysis");
  const runButton = document.getElementById("run");
  const progressEl = document.getElementById("progress");
  const statusEl = document.getElementById("job-status");
  const formError = document.getElementById("form-error");
  const state = {
    doc: null, analyses: {}, analysis: null, key: null, result: null, history: [], run: 0, units: () => ({}),
  };
  window.pipeflowStability = { state };

  const page = P.page({ form, formError, status: statusEl, button: runButton, state, progress: progressEl });

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

  const table = P.columnTable;

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
    drawFigures();
    SF.showWarnings(document.getElementById("warnings"), result.warnings);
  }

  function drawFigures() {
    const r = state.result;
    if (r) P.figures(document.getElementById("plots"), r.key, r.plots, state.units());
  }

  function share(key, spec) {
    SF.shareLink(document.getElementById("share-link"), { analysis: state.analysis, key, spec });
    document.getElementById("json-link").href = P.resultUrl(key);
    P.reportLinks(key);
  }

  // ---- API calls -------------------------------------------------------------------------

  function show(result, spec) {
    state.key = result.key;
    render(result);
    share(result.key, spec);
  }

  function run(event) {
    if (event) event.preventDefault();
    const a = state.analyses[state.analysis];
    return page.run({ endpoint: a.endpoint, spec: specFromForm, job: a.job, busy: "submitting…", show });
  }

  async function start() {
    state.doc = await (await fetch("openapi.json")).json();
    state.units = P.axisUnits(document.getElementById("axis-units"), state.doc, drawFigures);
    loadAnalyses(state.doc);
    const link = page.link();
    const name = state.analyses[link.params.get("analysis")] ? link.params.get("analysis") : "stability";
    showForm(name, link.spec);
    runButton.disabled = false;
    if (link.key) await page.open(link.key, (result) => show(result, link.spec));
  }

  form.addEventListener("submit", run);
  select.addEventListener("change", () => showForm(select.value));
  window.pipeflowStability.ready = start().catch((e) => { statusEl.textContent = String(e); });
})();
