// pipeflow stability page: every analysis of POST /v1/stability and POST /v1/sweeps with a
// form generated from the request schemas in /openapi.json (SchemaForm).  Sweeps run as
// jobs: progress is polled from GET /v1/jobs/{key} until the result is ready.  Results
// show a summary of the pipe's stability along the range (stable at its start or not, and
// how; every change of stability and its mechanism; the stable intervals; a critical
// velocity only as the first loss from a stable start), tables of it and of every crossing
// (stability boundary, sigma = 0 of a tracked branch, Campbell excitation lines) and the
// server's figures (pipeflow.io.plots, SVG), their
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
    document.getElementById("analysis-help").textContent = SF.helpText(a.description);
    SF.render(host, state.doc, a.schema, values || a.example || {});
  }

  function specFromForm() {
    const a = state.analyses[state.analysis];
    const spec = SF.collect(host, state.doc, a.schema);
    return a.job ? Object.assign({ [a.discriminator]: state.analysis }, spec) : spec;
  }

  // ---- results ---------------------------------------------------------------------------

  const table = P.columnTable;

  // ---- the stability along a range ---------------------------------------------------------
  // One picture for every analysis (issue 34): stable at the start of the range or not (and
  // how: divergence, flutter), every change of stability with its mechanism, the stable
  // intervals.  A critical velocity is only ever the first loss of stability from a stable
  // start; a range that starts unstable has none.

  const interval = (i) => "[" + fmt(i[0], 5) + ", " + fmt(i[1], 5) + "]";

  function mechanism(how) {
    return how && how.length ? how.join(" and ") : "mechanism not in this result";
  }

  function startState(p) {
    // "stable at v = 0 m/s" / "unstable at v = 0 m/s (divergence)"
    const at = p.name + " = " + fmt(p.x0, 5) + (p.unit ? " " + p.unit : "");
    return p.stable ? "stable at " + at : "unstable at " + at + " (" + mechanism(p.how) + ")";
  }

  function changeText(c, unit) {
    return (c.direction === "loss" ? "loses" : "regains") + " stability at " + fmt(c.x, 5)
      + (unit ? " " + unit : "") + " (" + c.kind + (c.mode ? ", mode " + c.mode : "") + ")";
  }

  function picture(p) {
    // the whole picture as sentences: start, every change, the stable intervals
    const unit = p.unit ? " " + p.unit : "";
    const first = startState(p);
    let text = first[0].toUpperCase() + first.slice(1);
    if (p.changes.length) text += "; " + p.changes.map((c) => changeText(c, p.unit)).join(", then ");
    text += ". Stable on " + (p.intervals.length ? p.intervals.map(interval).join(", ") + unit : "no part of the range") + ".";
    return text;
  }

  function firstLoss(p) {
    // the critical value: the first loss from a stable start, else null
    if (!p.stable) return null;
    const loss = p.changes.find((c) => c.direction === "loss");
    return loss || null;
  }

  function segments(p, end) {
    // the range cut at every change of stability: [{from, to, state, begins}]
    const out = [];
    let from = p.x0;
    let stable = p.stable;
    let begins = "start of the range" + (stable ? "" : " (" + mechanism(p.how) + ")");
    for (const c of p.changes) {
      out.push({ from, to: c.x, state: stable ? "stable" : "unstable", begins });
      from = c.x;
      stable = c.direction === "gain";
      begins = (c.direction === "loss" ? "loss by " : "regained: ") + c.kind + (c.mode ? ", mode " + c.mode : "");
    }
    out.push({ from, to: end, state: stable ? "stable" : "unstable", begins });
    return out;
  }

  function segmentTable(title, p, end) {
    const u = p.unit ? " [" + p.unit + "]" : " [-]";
    return table(title, [
      ["from " + p.name + u, (s) => s.from], ["to " + p.name + u, (s) => s.to],
      ["pipe", (s) => s.state], ["how it begins", (s) => s.begins],
    ], segments(p, end));
  }

  function linePicture(stable, how, crossings, intervals, x0, name, unit, value) {
    // a map's line (spin or beta): its picture from the result's arrays
    return {
      stable, how: how || [], name, unit, x0, intervals: intervals || [],
      changes: (crossings || []).map((c) => ({ x: value(c), direction: c.direction, kind: c.kind })),
    };
  }

  function sweepPicture(r) {
    // the pipe along an Argand or Campbell sweep (every eigenvalue, not the tracked ones)
    if (r.stable_at_start === undefined) return null; // a result of an earlier version
    const par = r.parameter;
    const name = par.name === "spin" ? "ω0" : "v";
    return {
      stable: r.stable_at_start, how: r.instability_at_start || [], name, unit: par.unit,
      x0: par.values[0], end: par.values[par.values.length - 1], intervals: r.stable_intervals || [],
      changes: (r.boundary || []).map((c) => ({ x: c.value, direction: c.direction, kind: c.kind })),
    };
  }

  const VIEWS = {
    stability(r) {
      const tables = [];
      let summary;
      if (r.stable_at_start === null || r.stable_at_start === undefined) {
        summary = "The range is reverse flow only (v < 0): no critical velocity (see the caveat below).";
      } else {
        const range = r.velocity_range || [0, 0];
        const p = {
          stable: r.stable_at_start, how: r.instability_at_start, name: "v", unit: "m/s",
          x0: Math.max(range[0], 0), intervals: r.stable_intervals || [],
          changes: (r.crossings || []).filter((c) => c.boundary)
            .map((c) => ({ x: c.velocity, direction: c.direction, kind: c.kind, mode: c.mode })),
        };
        const loss = firstLoss(p);
        const from = "v = " + fmt(p.x0, 5) + " m/s" + (p.x0 > 0 ? " (the start of the range; below it is not analysed)" : "");
        const u = r.dimensionless && r.dimensionless.u_cr;
        const head = !p.stable
          ? "No critical velocity: at ω0 = " + fmt(r.omega0) + " rad/s the pipe is already unstable at " + from + "."
          : loss
            ? "Critical velocity v_cr = " + fmt(loss.x) + " m/s (u_cr = " + fmt(u, 4) + ") at ω0 = " + fmt(r.omega0)
              + " rad/s: the first loss of stability from " + from + ", by " + loss.kind + (loss.mode ? " of mode " + loss.mode : "") + "."
            : "Stable over the whole range at ω0 = " + fmt(r.omega0) + " rad/s.";
        summary = head + " " + picture(p);
        tables.push(segmentTable("Stability along the range", p, range[1]));
      }
      tables.push(table("Every crossing of σ = 0", [
        ["velocity [m/s]", (c) => c.velocity], ["frequency [rad/s]", (c) => c.frequency],
        ["frequency [Hz]", (c) => c.frequency_hz], ["mode", (c) => c.mode], ["kind", (c) => c.kind],
        ["direction", (c) => c.direction], ["boundary", (c) => c.boundary], ["flow number u [-]", (c) => c.flow_number],
      ], r.crossings || []));
      return { summary, unstable: !r.stable_throughout, tables };
    },
    argand(r) {
      const zeros = r.zero_crossings || [];
      const p = sweepPicture(r);
      const tracked = table("Crossings of σ = 0 by the tracked branches", [
        ["velocity [m/s]", (c) => c.value], ["frequency [rad/s]", (c) => c.frequency],
        ["mode", (c) => c.mode], ["direction", (c) => c.direction],
      ], zeros);
      if (!p) {
        return {
          summary: zeros.length ? "The tracked branches cross σ = 0 " + zeros.length + " times (table)." : "No tracked branch crosses σ = 0.",
          unstable: zeros.length > 0, tables: [tracked],
        };
      }
      const loss = firstLoss(p);
      const head = !p.stable ? "No critical velocity: the pipe is already unstable at the start of the sweep."
        : loss ? "Critical velocity v_cr = " + fmt(loss.x) + " m/s: the first loss of stability from v = " + fmt(p.x0, 5) + " m/s, by " + loss.kind + "."
          : "Stable over the whole sweep.";
      return {
        summary: head + " " + picture(p),
        unstable: !(p.stable && !loss),
        tables: [segmentTable("Stability along the sweep (every eigenvalue)", p, p.end), tracked],
      };
    },
    campbell(r) {
      const exc = r.excitation || { orders: [], crossings: [] };
      const zeros = r.zero_crossings || [];
      const p = sweepPicture(r);
      const head = "Excitation orders " + exc.orders.map((n) => fmt(n) + "x").join(", ") + ": "
        + exc.crossings.length + " crossings with the tracked branches at v = " + fmt((r.fixed || {}).velocity) + " m/s.";
      const tables = [table("Crossings of the excitation lines ω = n ω0", [
        ["order n", (c) => c.order], ["mode", (c) => c.mode], ["spin [rad/s]", (c) => c.spin],
        ["spin [rpm]", (c) => c.spin_rpm], ["frequency [rad/s]", (c) => c.frequency],
        ["σ [1/s]", (c) => c.sigma], ["damping ratio ζ [-]", (c) => c.damping_ratio],
      ], exc.crossings)];
      if (p) tables.push(segmentTable("Stability along the sweep (every eigenvalue)", p, p.end));
      tables.push(table("Crossings of σ = 0 by the tracked branches", [
        ["spin [rad/s]", (c) => c.value], ["frequency [rad/s]", (c) => c.frequency],
        ["mode", (c) => c.mode], ["direction", (c) => c.direction],
      ], zeros));
      return {
        summary: head + (p ? " " + picture(p) : ""),
        unstable: p ? !(p.stable && p.changes.length === 0) : zeros.length > 0,
        tables,
      };
    },
    spin_map(r) {
      const x0 = Math.max(r.velocities[0], 0);
      const rows = r.spins.map((w, i) => {
        const how = (r.instability_at_start || [])[i];
        const p = linePicture(r.stable_at_start[i], how, r.crossings[i], (r.stable_intervals || [])[i],
          x0, "v", "m/s", (c) => c.velocity);
        const loss = firstLoss(p);
        return {
          w, rpm: r.spins_rpm[i], p,
          start: p.stable ? "stable" : "unstable (" + mechanism(p.how) + ")",
          vcr: !p.stable ? "none: unstable at v = " + fmt(x0, 5) + " m/s" : loss ? loss.x : "none in the range",
          stable: p.intervals.length ? p.intervals.map(interval).join(", ") : "nowhere",
          changes: p.changes.length ? p.changes.map((c) => (c.direction === "loss" ? "loss " : "gain ") + fmt(c.x, 5) + " (" + c.kind + ")").join("; ") : "none",
        };
      });
      const atRest = rows.filter((x) => x.p.stable);
      const losing = atRest.filter((x) => typeof x.vcr === "number");
      const unstable = rows.filter((x) => !x.p.stable);
      const kinds = [...new Set(unstable.flatMap((x) => x.p.how))];
      const at = "v = " + fmt(x0, 5) + " m/s";
      let summary = "At " + atRest.length + " of " + rows.length + " spins the pipe is stable at " + at;
      summary += losing.length ? " and loses stability at v_cr from " + fmt(Math.min(...losing.map((x) => x.vcr)), 4)
        + " to " + fmt(Math.max(...losing.map((x) => x.vcr)), 4) + " m/s." : ".";
      if (unstable.length) {
        summary += " At " + unstable.length + " spin" + (unstable.length > 1 ? "s" : "") + " (the lowest ω0 = " + fmt(unstable[0].w) + " rad/s) it is already unstable at " + at
          + " (" + (kinds.length ? kinds.join(" and ") : "mechanism not in this result") + "): no critical velocity there; the table gives where it is stable.";
      }
      return {
        summary,
        unstable: rows.some((x) => !x.p.stable || x.p.changes.length > 0),
        tables: [table("Stability per spin", [
          ["spin [rad/s]", (x) => x.w], ["spin [rpm]", (x) => x.rpm], ["at " + at, (x) => x.start],
          ["v_cr: first loss from " + at + " [m/s]", (x) => x.vcr], ["stable on [m/s]", (x) => x.stable],
          ["changes of stability [m/s]", (x) => x.changes],
        ], rows)],
      };
    },
    beta_map(r) {
      const u0 = r.u_range[0];
      const rows = r.betas.map((b, i) => {
        const how = (r.instability_at_start || [])[i];
        const p = linePicture(r.stable_at_start[i], how, r.crossings[i], (r.stable_intervals || [])[i],
          u0, "u", "", (c) => c.u);
        const loss = firstLoss(p);
        return {
          b, p,
          start: p.stable ? "stable" : "unstable (" + mechanism(p.how) + ")",
          u: !p.stable ? "none: unstable at u = " + fmt(u0, 5) : loss ? loss.x : "none in the range",
          stable: p.intervals.length ? p.intervals.map(interval).join(", ") : "nowhere",
          changes: p.changes.length ? p.changes.map((c) => (c.direction === "loss" ? "loss " : "gain ") + fmt(c.x, 5) + " (" + c.kind + ")").join("; ") : "none",
        };
      });
      const unstable = rows.filter((x) => !x.p.stable);
      return {
        summary: "u_cr(β) at γ = " + fmt(r.gamma) + ": the first loss of stability from u = " + fmt(u0, 5) + "; "
          + (r.multiple_crossings || []).length + " mass ratios with more than one crossing (S-shaped segments)."
          + (unstable.length ? " At " + unstable.length + " mass ratios the pipe is already unstable at u = " + fmt(u0, 5)
            + ": no u_cr there; the table gives where it is stable." : ""),
        unstable: rows.some((x) => !x.p.stable || x.p.changes.length > 0),
        tables: [table("Stability per mass ratio", [
          ["β [-]", (x) => x.b], ["at u = " + fmt(u0, 5), (x) => x.start],
          ["u_cr: first loss from u = " + fmt(u0, 5) + " [-]", (x) => x.u], ["stable on [-]", (x) => x.stable],
          ["changes of stability [-]", (x) => x.changes],
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
