// pipeflow pages: what the pages (simulation, stability, frequency response, studies) share,
// loaded after schemaform.js and before the page's own script.  Number formats and axis
// ticks, result URLs, tables of rows and the server's figures (their spin and frequency
// axes in rad/s, rpm or Hz), a result's report links (HTML, PDF), the link a page is opened
// with (?key=..., ?spec=...), the examples chooser, and a page's run: a request posted from
// the form, a job polled with a progress bar until its result is ready (a newer run stops an
// older one), its result brought into view (scrolled to and focused), a result opened by
// key, and the error shown in the status line.
"use strict";

window.PipeflowPages = (function () {
  const SF = window.SchemaForm;
  const POLL_MS = 250;

  // ---- formats -----------------------------------------------------------------------------

  function fmt(v, digits) {
    // a table cell: "—" for a missing value, integers as they are, else 6 significant digits
    if (v === null || v === undefined) return "—";
    if (typeof v !== "number") return String(v);
    return Number.isInteger(v) ? String(v) : +v.toPrecision(digits || 6) + "";
  }

  function tickFormat(expDigits) {
    // axis labels that stay short and readable from 1e-9 to 1e300 (the exponent form beyond
    // 1e4 and below 1e-2), never "Infinity" or a 300-digit number; with ``expDigits`` the
    // exponent form has that many decimals, trailing zeros dropped (else one decimal)
    return (v) => {
      if (v === null || !Number.isFinite(v)) return "";
      if (v === 0) return "0";
      const a = Math.abs(v);
      if (a >= 1e4 || a < 1e-2) {
        return expDigits ? v.toExponential(expDigits).replace("e+", "e").replace(/\.?0+e/, "e")
          : v.toExponential(1).replace("e+", "e");
      }
      return String(+v.toPrecision(6));
    };
  }

  const tick = tickFormat(0);

  // uPlot needs null where a value is missing or not a finite number (overflow); a log axis
  // null where it is not positive
  const finite = (values) => values.map((v) => (typeof v === "number" && Number.isFinite(v) ? v : null));
  const positive = (values) => values.map((v) => (typeof v === "number" && Number.isFinite(v) && v > 0 ? v : null));

  function chartWidth(el, fallback) {
    // a chart as wide as its box, 320 .. 1000 px
    return Math.max(320, Math.min(el.clientWidth || fallback, 1000));
  }

  const short = (key) => key.slice(0, 12) + "…";
  const resultUrl = (key) => "v1/results/" + encodeURIComponent(key);
  const jobUrl = (key) => "v1/jobs/" + encodeURIComponent(key);

  async function fetchResult(key) {
    const response = await fetch(resultUrl(key), { headers: { Accept: "application/json" } });
    if (!response.ok) throw await SF.problemOf(response);
    return await response.json();
  }

  // ---- tables and figures ------------------------------------------------------------------

  function table(title, headers, rows, note) {
    // a titled table of rows of values (fmt), with an optional note above it
    const wrap = document.createElement("div");
    const h = document.createElement("h2");
    h.textContent = title;
    const t = document.createElement("table");
    t.className = "data";
    const head = t.createTHead().insertRow();
    for (const label of headers) {
      const th = document.createElement("th");
      th.textContent = label;
      head.appendChild(th);
    }
    const body = t.createTBody();
    for (const row of rows) {
      const tr = body.insertRow();
      for (const v of row) tr.insertCell().textContent = fmt(v);
    }
    wrap.append(h);
    if (note) {
      const p = document.createElement("p");
      p.className = "note";
      p.textContent = note;
      wrap.append(p);
    }
    wrap.append(t);
    wrap.dataset.rows = String(rows.length);
    return wrap;
  }

  function columnTable(title, columns, items) {
    // a table of items, one column per [label, getter]; the title counts the items
    return table(title + " (" + items.length + ")", columns.map((c) => c[0]),
      items.map((item) => columns.map((c) => c[1](item))));
  }

  function figures(box, key, names, units) {
    // the server's figures of a result: each as SVG, captioned with a link to its PNG;
    // ``units`` ({spin, frequency}: the axes' units, the API's plot query) when not rad/s
    box.textContent = "";
    const query = new URLSearchParams();
    for (const [q, u] of Object.entries(units || {})) if (u && u !== "rad/s") query.set(q + "_unit", u);
    const suffix = query.toString() ? "?" + query.toString() : "";
    for (const name of names || []) {
      const fig = document.createElement("figure");
      const img = document.createElement("img");
      const base = resultUrl(key) + "/plots/" + name;
      img.src = base + ".svg" + suffix;
      img.alt = name;
      img.dataset.plot = name;
      const cap = document.createElement("figcaption");
      const a = document.createElement("a");
      a.href = base + ".png" + suffix;
      a.textContent = name + " (PNG)";
      cap.appendChild(a);
      fig.append(img, cap);
      box.appendChild(fig);
    }
  }

  function plotUnits(doc) {
    // the axis units the API's figures offer, from its plot operation's query parameters:
    // {spin: ["rad/s", "rpm", "Hz"], frequency: [...]} (rad/s when the document has none)
    const out = { spin: ["rad/s"], frequency: ["rad/s"] };
    const op = ((doc.paths || {})["/v1/results/{key}/plots/{name}.{fmt}"] || {}).get || {};
    for (const p of op.parameters || []) {
      const m = /^(spin|frequency)_unit$/.exec(p.name);
      if (m && p.schema && Array.isArray(p.schema.enum)) out[m[1]] = p.schema.enum.slice();
    }
    return out;
  }

  function axisUnits(box, doc, onChange) {
    // "spin axis [rad/s|rpm|Hz] frequency axis [rad/s|Hz|rpm]" selects in ``box``; returns
    // a function giving the chosen {spin, frequency}; ``onChange`` redraws
    const offered = plotUnits(doc);
    box.textContent = "";
    const selects = {};
    for (const [q, units] of Object.entries(offered)) {
      const label = document.createElement("label");
      label.className = "inline";
      label.textContent = q + " axis ";
      const select = document.createElement("select");
      select.id = q + "-axis-unit";
      select.dataset.axis = q;
      for (const u of units) select.add(new Option(u, u));
      select.addEventListener("change", onChange);
      label.appendChild(select);
      box.appendChild(label);
      selects[q] = select;
    }
    return () => Object.fromEntries(Object.entries(selects).map(([q, s]) => [q, s.value]));
  }

  function reportLinks(key) {
    // every a[data-report="html"|"pdf"] of the page: the report of result ``key``
    for (const a of document.querySelectorAll("a[data-report]")) {
      a.href = resultUrl(key) + "/report." + a.dataset.report;
    }
  }

  function reveal() {
    // the result of a Run brought into view: the forms are taller than a window (the
    // simulation's ~1,700 px), so #results is scrolled to the window's top and focused
    // (keyboard and screen-reader users land on it; tabindex -1: not a tab stop)
    const el = document.getElementById("results");
    if (!el || el.hidden) return;
    if (!el.hasAttribute("tabindex")) el.setAttribute("tabindex", "-1");
    el.scrollIntoView({ block: "start" });
    el.focus({ preventScroll: true });
  }

  // ---- the examples chooser ----------------------------------------------------------------

  function examplesChooser(select, examples, chosen, pick, suffix) {
    // "(as in the link)" and one option per named example ("name: summary"); choosing one
    // hands a copy of its value to ``pick``
    select.add(new Option("(as in the link)", ""));
    for (const [name, ex] of Object.entries(examples)) {
      select.add(new Option(name + (ex.summary ? ": " + ex.summary : "") + (suffix ? suffix(name) : ""), name));
    }
    select.value = chosen;
    select.addEventListener("change", () => {
      const ex = examples[select.value];
      if (ex) pick(JSON.parse(JSON.stringify(ex.value)));
    });
  }

  // ---- a page: its form, status line, progress bar and runs -------------------------------

  function page(o) {
    // o: form, formError, status (the status line), button (Run), state (run: the current
    // run's token, history: the job states seen), progress (a <progress>, or null)
    const state = o.state;

    function problemText(problem) {
      // a problem (RFC 9457) shown at its fields; anything else (a network error) as text
      return problem && problem.title !== undefined
        ? SF.showProblem(o.form, problem, o.formError) : "error: " + String(problem && problem.message || problem);
    }

    function link() {
      // the query the page was opened with: key and spec (JSON) of a shared result
      const params = new URLSearchParams(window.location.search);
      let spec = null;
      if (params.get("spec")) {
        try { spec = JSON.parse(params.get("spec")); } catch (e) { o.status.textContent = "bad spec in link"; }
      }
      return { params, spec, key: params.get("key") };
    }

    function showJob(job) {
      state.history.push({ status: job.status, progress: job.progress });
      o.progress.hidden = false;
      o.progress.value = job.progress;
      o.status.textContent = job.status + " " + Math.round(100 * job.progress) + " %";
    }

    async function follow(job, token) {
      // poll the job until it is finished; a newer run stops this one (null)
      for (;;) {
        if (token !== state.run) return null;
        showJob(job);
        if (job.status === "succeeded") return await fetchResult(job.key);
        if (job.status === "failed" || job.status === "cancelled") throw job.error || { title: "job " + job.status };
        await new Promise((r) => setTimeout(r, POLL_MS));
        const response = await fetch(jobUrl(job.key), { headers: { Accept: "application/json" } });
        if (!response.ok) throw await SF.problemOf(response);
        job = await response.json();
      }
    }

    function begin() {
      // a new run: its token; older runs still polling stop
      const token = ++state.run;
      if (o.progress) state.history = [];
      SF.clearErrors(o.form);
      return token;
    }

    async function run(r) {
      // r: endpoint, spec (a function: read after the errors are cleared), job (the answer is
      // a job to follow), busy (status text while posting), show(result, spec)
      const token = begin();
      const spec = r.spec();
      o.button.disabled = true;
      o.status.textContent = r.busy;
      if (o.progress) {
        o.progress.hidden = !r.job;
        o.progress.value = 0;
      }
      try {
        const answer = await SF.post(r.endpoint, spec, o.form, o.formError);
        if (!answer.ok) { o.status.textContent = answer.title; return; }
        const result = r.job ? await follow(answer.body, token) : answer.body;
        if (!result || token !== state.run) return;
        r.show(result, spec);
        reveal();
        o.status.textContent = r.job ? "done (job " + short(result.key) + ")"
          : "done (" + (result.cached ? "cached" : "computed") + ")";
      } catch (problem) {
        o.status.textContent = problemText(problem);
      } finally {
        if (token === state.run) o.button.disabled = false;
      }
    }

    async function open(key, show, job) {
      // a result by key; with ``job`` its job is followed while it runs (a stored result
      // has no job: loaded)
      const token = begin();
      o.status.textContent = "loading " + short(key);
      try {
        let result;
        if (job) {
          const response = await fetch(jobUrl(key), { headers: { Accept: "application/json" } });
          result = response.ok ? await follow(await response.json(), token) : await fetchResult(key);
        } else {
          result = await fetchResult(key);
        }
        if (!result || token !== state.run) return;
        show(result);
        o.status.textContent = "loaded result " + short(key);
      } catch (problem) {
        o.status.textContent = problemText(problem);
      }
    }

    return { problemText, link, run, open, follow };
  }

  return {
    fmt, tick, tickFormat, finite, positive, chartWidth, short, resultUrl, fetchResult, table, columnTable, figures,
    plotUnits, axisUnits, reportLinks, examplesChooser, page, reveal,
  };
})();
