// Forms generated from the service's own OpenAPI document (GET openapi.json), so every
// field, method, profile kind and default the API has appears here and stays in step with
// it.  Used by the simulation viewer (index.html), the stability, frequency-response and
// study pages.
//
// A request schema is walked after resolving $refs:
// - an object becomes a fieldset (optional groups whose fields all have defaults are
//   collapsed in a <details>), a discriminated union (oneOf + discriminator, e.g. the
//   profiles constant / polynomial / harmonic / table) a kind <select> with one block
//   of fields per kind;
// - an array of objects (e.g. the simulation's loads, the frequency response's
//   operating_points) a list editor: one block per item (a discriminated item with its kind
//   <select>), "add" and "remove" buttons within the schema's minItems / maxItems; an empty
//   list is not sent (its default, or null, applies);
// - a map (an object of patternProperties / additionalProperties, e.g. a study's grid or
//   its sampled parameters: field path -> values or distribution) a map editor: one entry
//   per key, a key input and the value's own fields, "add" and "remove" buttons; an empty
//   map is not sent;
// - an enum becomes a <select> (with an empty choice for "enum or null"), a boolean a
//   checkbox, a number, string or array of numbers a text input (arrays as "a, b, c");
//   "X or null" is X, left empty for null, and an optional block ("object or null") is sent only when its "include" box is ticked;
// - every field shows its description as one plain sentence (helpText: the docstrings' reST
//   unmarked), with the unit the description states in brackets
//   ("[m/s]") next to its name; initial values are the given values (an example), else the
//   schema's defaults.  A number's bounds (minimum, maximum, exclusive ones) are its
//   input's tooltip and are checked as it is typed; a profile's fields without a unit of
//   their own (value, mean, amplitude, ...) show the unit of the quantity they profile
//   ("force [N]": "amplitude [N]").
// - a number (or list of numbers) that the API also takes as a quantity ({"value", "unit"},
//   converted to SI at validation) in metres, rad/s or m/s gets a unit <select> beside it: m
//   or mm; rad/s, rpm or Hz (cycles per second); m/s, mm/s, km/h or ft/s.  The SI unit sends the plain number; another
//   sends {"value": 3000, "unit": "rpm"} (a polynomial's coefficient c_k in unit/s^k), so
//   the API's cache key is the same for the same physics.
// Inputs are named by the dotted JSON path ("flow.velocity.coefficients"), which is also
// how the API names a bad field in problem+json errors[].field.
"use strict";

window.SchemaForm = (function () {
  function deref(doc, schema) {
    // follow $ref (keeping the referring node's own description/default/title)
    let s = schema || {};
    const seen = new Set();
    while (s.$ref && !seen.has(s.$ref)) {
      seen.add(s.$ref);
      const target = s.$ref.replace(/^#\//, "").split("/").reduce((o, k) => o[k], doc);
      const own = Object.assign({}, s);
      delete own.$ref;
      s = Object.assign({}, target, own);
    }
    if (Array.isArray(s.anyOf)) {
      // a number that also takes {"value", "unit"} (the API converts it to SI): the form
      // asks for the SI number its label states
      const quantity = (o) => typeof o.$ref === "string" && /\/Quantity$/.test(o.$ref);
      const nullable = s.anyOf.some((o) => o.type === "null");
      const others = s.anyOf.filter((o) => o.type !== "null" && !quantity(o));
      if (others.length === 1 && others.length < s.anyOf.length) {
        const own = Object.assign({}, s);
        delete own.anyOf;
        s = Object.assign({}, deref(doc, others[0]), own, nullable ? { nullable: true } : {},
          s.anyOf.some(quantity) ? { quantity: true } : {});
      } else {
        // a named choice or an object (an end support: "pinned" ... or {"translational":
        // k}): the form offers the names; the object form goes in the JSON body
        const named = others.filter((o) => Array.isArray(o.enum));
        // a number or a profile (an internal pressure): the form offers the profiles, whose
        // constant kind is the number's request (the API gives both one key)
        const unions = others.filter((o) => isUnion(o));
        if (named.length === 1 && others.length > 1) {
          const own = Object.assign({}, s);
          delete own.anyOf;
          s = Object.assign({}, named[0], own, nullable ? { nullable: true } : {});
        } else if (unions.length === 1 && others.length > 1) {
          const own = Object.assign({}, s);
          delete own.anyOf;
          if (typeof own.default !== "object") delete own.default;
          s = Object.assign({}, unions[0], own);
        }
      }
    }
    if (s.items && typeof s.items === "object" && Array.isArray(s.items.anyOf)) {
      s = Object.assign({}, s, { items: deref(doc, s.items) });
    }
    return s;
  }

  function requestSchema(doc, path) {
    const op = doc.paths[path].post;
    const content = op.requestBody.content["application/json"];
    return { schema: deref(doc, content.schema), examples: content.examples || {} };
  }

  function unitOf(s) {
    const d = s.description || "";
    const m = d.match(/\[([^\]]*)\]/);
    return m ? m[1] : null;
  }

  //: the units offered beside a field that takes a quantity, by its SI unit (the first);
  //: pint's names, as the API reads them (Hz: cycles per second, 1 Hz = 2 pi rad/s)
  const UNIT_CHOICES = {
    "m": ["m", "mm"], "rad/s": ["rad/s", "rpm", "Hz"], "m/s": ["m/s", "mm/s", "km/h", "ft/s"],
  };
  //: each choice in its SI unit (for the bounds checked while typing; the API converts)
  const TO_SI = {
    "m": 1, "mm": 1e-3, "rad/s": 1, "rpm": (2 * Math.PI) / 60, "Hz": 2 * Math.PI,
    "m/s": 1, "mm/s": 1e-3, "km/h": 1 / 3.6, "ft/s": 0.3048,
  };

  function helpText(description) {
    // a field's description as a help text: one plain sentence.  The descriptions come from
    // the models' docstrings, in reST: roles unwrapped (:class:`~a.b.C` -> C, :math:`x` -> x,
    // :func:`text <target>` -> text), literals and emphasis unmarked (``x``, `x`, **x**),
    // whitespace collapsed; an opening plain lowercase word capitalised (after a "name: "
    // label such as a method's, which stays as written), and a full stop if none ends it
    let t = String(description || "").replace(/\s+/g, " ").trim();
    t = t.replace(/:[a-z]+(?::[a-z]+)?:`(~?)([^`]*?)`/g, (m, tilde, body) => {
      const text = body.replace(/\s*<[^>]*>$/, "");
      return tilde ? text.split(".").pop() : text;
    });
    t = t.replace(/``([^`]*)``/g, "$1").replace(/`([^`]*)`/g, "$1").replace(/\*\*([^*]+)\*\*/g, "$1");
    if (!t) return t;
    t = t.replace(/^((?:[a-z0-9_/]+: )?)([a-z]{2,})(?=[ ,;:.]|$)/, (m, label, word) => label + word[0].toUpperCase() + word.slice(1));
    return /[.!?]["'\u2019)\]]*$/.test(t) ? t : t + ".";
  }

  function isQuantity(v) {
    return !!v && typeof v === "object" && !Array.isArray(v) && "value" in v && "unit" in v;
  }

  function unitChoice(s, unit, numeric) {
    // the unit <select>'s options for this field, or null: a number (or numbers) the API
    // also takes as a quantity, whose SI unit has alternatives; a polynomial's coefficients
    // ("[rad/s]/s^k") in that unit per s^k
    if (!numeric || !unit) return null;
    const takes = s.quantity || (s.items && s.items.quantity);
    const perPower = /\/s\^k$/.test(unit);
    const si = unit.replace(/\/s\^k$/, "");
    return takes && UNIT_CHOICES[si] ? { si, perPower, units: UNIT_CHOICES[si] } : null;
  }

  function unitSelect(choice, given) {
    // given: the unit of the initial value (a quantity in a shared link), kept if unknown here
    const select = el("select", { class: "unit", "data-unit-si": choice.si, title: "unit" });
    const units = choice.units.includes(given) || !given ? choice.units : choice.units.concat([given]);
    for (const u of units) {
      select.add(new Option(u + (choice.perPower ? "/s^k" : ""), u, false, u === (given || choice.si)));
    }
    select.dataset.perPower = choice.perPower ? "1" : "";
    return select;
  }

  function withUnit(input, v) {
    // the value read from ``input`` in the unit its <select> shows: the number itself in the
    // SI unit, else {"value", "unit"} (each element of a list; coefficient k in unit / s^k)
    const select = input && input.unitSelect;
    if (!select || select.value === select.dataset.unitSi || v === undefined || v === null) return v;
    const u = select.value;
    const q = (x, k) => (typeof x === "number"
      ? { value: x, unit: select.dataset.perPower && k ? u + " / s ** " + k : u } : x);
    return Array.isArray(v) ? v.map(q) : q(v, 0);
  }

  function quantityOf(input) {
    // what a number field holds, with its unit (a page's copy of one field into another)
    return input ? withUnit(input, numberOrRaw(input.value)) : undefined;
  }

  function groupUnit(s) {
    // the unit of a whole group (a profile: "Force F(t) [N] ..."): a bracket in the
    // description's opening words, not one inside a list of examples ("'point_force' at a
    // position [m]", "{velocity [m/s], ...}")
    const d = s.description || "";
    const i = d.indexOf("[");
    if (i < 0 || /['{:;]/.test(d.slice(0, i))) return null;
    const u = unitOf(s);
    return u && u !== "-" ? u : null;
  }

  function isProfile(s) {
    // an object tagged by a constant kind (ConstantProfile behind a plain $ref)
    return isObject(s) && !!s.properties.kind && s.properties.kind.const !== undefined;
  }

  function isUnion(s) {
    return Array.isArray(s.oneOf) && s.discriminator && s.discriminator.mapping;
  }

  function isObject(s) {
    return !!s.properties;
  }

  function mapValue(doc, s) {
    // the value schema of a map (an object keyed by free names, e.g. field paths), else null
    if (isObject(s) || s.type !== "object") return null;
    const pattern = s.patternProperties && Object.values(s.patternProperties)[0];
    const extra = s.additionalProperties && typeof s.additionalProperties === "object" ? s.additionalProperties : null;
    return pattern || extra ? deref(doc, pattern || extra) : null;
  }

  function itemSchema(doc, s) {
    // the item schema of an array of objects (a union, an object or a map), else null
    if (s.type !== "array" || !s.items || typeof s.items !== "object") return null;
    const item = deref(doc, s.items);
    return isUnion(item) || isObject(item) || mapValue(doc, item) ? item : null;
  }

  function bounds(s) {
    // "(0, 1e4]" from the schema's (exclusive) minimum and maximum, or null
    const lo = s.exclusiveMinimum !== undefined ? ["(", s.exclusiveMinimum]
      : s.minimum !== undefined ? ["[", s.minimum] : null;
    const hi = s.exclusiveMaximum !== undefined ? [s.exclusiveMaximum, ")"]
      : s.maximum !== undefined ? [s.maximum, "]"] : null;
    if (!lo && !hi) return null;
    return (lo ? lo[0] + show(lo[1]) : "(-∞") + ", " + (hi ? show(hi[0]) + hi[1] : "∞)");
  }

  function outOfRange(s, x) {
    return (s.minimum !== undefined && x < s.minimum) || (s.maximum !== undefined && x > s.maximum)
      || (s.exclusiveMinimum !== undefined && x <= s.exclusiveMinimum)
      || (s.exclusiveMaximum !== undefined && x >= s.exclusiveMaximum)
      || (s.type === "integer" && !Number.isInteger(x));
  }

  function show(x) {
    // 7800000000 -> "7.8e9", as a person would type it
    if (typeof x !== "number" || x === 0) return String(x);
    const a = Math.abs(x);
    return a >= 1e6 || a < 1e-3 ? x.toExponential().replace("e+", "e") : String(x);
  }

  function el(tag, attrs, text) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v !== undefined && v !== null && v !== false) e.setAttribute(k, v === true ? "" : v);
    }
    if (text !== undefined) e.textContent = text;
    return e;
  }

  function allDefaults(doc, s) {
    // every leaf of this object has a default (so the whole group may stay collapsed)
    if (s.nullable) return true;
    if (isUnion(s)) return s.default !== undefined;
    if (!isObject(s)) return s.default !== undefined || s.nullable || s.type === "array";
    return (s.required || []).length === 0
      && Object.values(s.properties).every((p) => allDefaults(doc, deref(doc, p)));
  }

  function leaf(doc, s, path, name, value, required, inherit) {
    const v = value !== undefined ? value : s.default;
    const numeric = s.type === "number" || s.type === "integer"
      || (s.type === "array" && s.items && s.items.type === "number");
    // a profile's value/mean/amplitude/values: the unit of the profiled quantity
    // (coefficients c_k: that unit per s^k, as their description says)
    const unit = unitOf(s) || (inherit && numeric
      ? inherit + (/\/s\^k/.test(s.description || "") ? "/s^k" : "") : null);
    const choice = unitChoice(s, unit, numeric && s.type !== "integer");
    // a quantity given (a shared link): its number in the field, its unit in the select
    let given = null;
    let shown = v;
    if (choice && isQuantity(v)) {
      given = String(v.unit);
      shown = v.value;
    } else if (choice && Array.isArray(v) && v.some(isQuantity)) {
      const first = v.find(isQuantity);
      given = String(first.unit).replace(/\s*\/\s*s\s*\*\*\s*\d+$/, "");
      shown = v.map((x) => (isQuantity(x) ? x.value : x));
    }
    const label = el("label", { class: "field", title: helpText(s.description) });
    const nameEl = el("span", { class: "name" }, name + (unit && unit !== "-" ? " [" + unit + "]" : ""));
    label.append(nameEl);
    let input;
    if (Array.isArray(s.enum)) {
      input = el("select", { name: path, "data-field": path, "data-type": "enum" });
      // "name or null" (pipe.material): an empty choice, sent as nothing (the default)
      if (s.nullable) input.add(new Option("", "", false, v === undefined || v === null));
      for (const option of s.enum) {
        input.add(new Option(String(option), String(option), false, option === v));
      }
    } else if (s.type === "boolean") {
      input = el("input", { type: "checkbox", name: path, "data-field": path, "data-type": "boolean" });
      input.checked = v === true;
    } else {
      const kind = s.type === "array" || s.prefixItems ? "array" : s.type || "string";
      const text = shown === undefined || shown === null ? ""
        : Array.isArray(shown) ? shown.map(show).join(", ") : show(shown);
      input = el("input", {
        name: path, "data-field": path, "data-type": kind, value: text,
        placeholder: s.nullable ? "auto (null)" : required ? "required" : "",
      });
      if (kind === "array") input.classList.add("wide");
      const range = bounds(s) && bounds(s) + (choice ? " " + choice.si : "");
      if (range && kind !== "array") {
        input.title = "allowed: " + range;
        input.dataset.bounds = range;
        input.addEventListener("input", () => {
          // the schema's bounds (SI), checked while typing (the API checks them again)
          const scale = input.unitSelect ? TO_SI[input.unitSelect.value] || NaN : 1;
          const x = Number(input.value.trim()) * scale;
          const bad = input.value.trim() !== "" && Number.isFinite(x) && outOfRange(s, x);
          input.classList.toggle("invalid", bad);
          const slot = input.closest(".leaf").querySelector("[data-error-for]");
          slot.textContent = bad ? "allowed: " + range : "";
        });
      }
    }
    label.append(input);
    if (choice) {
      // the unit beside the number (label.field.with-unit: a grid), named in the label too
      const select = unitSelect(choice, given);
      select.dataset.unitFor = path;
      input.unitSelect = select;
      const named = () => {
        input.dataset.unit = select.value;
        nameEl.textContent = name + " [" + select.selectedOptions[0].textContent + "]";
      };
      named();
      select.addEventListener("change", () => {
        named();
        input.dispatchEvent(new Event("input"));  // the bounds, in the new unit
      });
      label.classList.add("with-unit");
      label.append(select);
    }
    if (s.description) label.append(el("small", { class: "help" }, helpText(s.description)));
    const wrap = el("div", { class: "leaf" });
    wrap.append(label, el("span", { class: "error", "data-error-for": path }));
    return wrap;
  }

  function union(doc, s, path, name, value) {
    const disc = s.discriminator.propertyName;
    const kinds = Object.keys(s.discriminator.mapping);
    const chosen = (value && value[disc]) || (s.default && s.default[disc]) || kinds[0];
    const fs = el("fieldset", { class: "union", "data-union": path });
    const unit = groupUnit(s);
    fs.append(el("legend", {}, name + (unit ? " [" + unit + "]" : "")));
    if (s.description) fs.append(el("small", { class: "help block" }, helpText(s.description)));
    const label = el("label", { class: "field" });
    label.append(el("span", { class: "name" }, disc));
    const select = el("select", { name: path + "." + disc, "data-field": path, "data-type": "kind" });
    for (const k of kinds) select.add(new Option(k, k, false, k === chosen));
    label.append(select);
    const head = el("div", { class: "leaf" });
    head.append(label, el("span", { class: "error", "data-error-for": path }));
    fs.append(head);
    for (const k of kinds) {
      const variant = deref(doc, { $ref: s.discriminator.mapping[k] });
      const block = el("div", { class: "kind", "data-kind": k });
      if (variant.description) block.append(el("small", { class: "help block" }, k + ": " + helpText(variant.description)));
      const given = value && value[disc] === k ? value : undefined;
      fields(doc, variant, path, given, block, disc, unit);
      block.hidden = k !== chosen;
      fs.append(block);
    }
    select.addEventListener("change", () => {
      for (const b of fs.querySelectorAll(":scope > .kind")) b.hidden = b.dataset.kind !== select.value;
    });
    return fs;
  }

  function node(doc, schema, path, name, value, required, inherit) {
    const s = deref(doc, schema);
    if (isUnion(s)) return union(doc, s, path, name, value);
    if (itemSchema(doc, s)) return list(doc, s, path, name, value);
    if (mapValue(doc, s)) return map(doc, s, path, name, value);
    if (isObject(s)) {
      const fs = el("fieldset", { class: "group", "data-group": path });
      let body = fs;
      if (s.nullable) {
        // an optional block that is null unless switched on (e.g. output.mode_shapes)
        body = el("details", { "data-group": path });
        body.open = value !== undefined && value !== null;
        body.append(el("summary", {}, name + " (optional)"));
        const on = el("label", { class: "field switch" });
        const box = el("input", { type: "checkbox", name: path + ".enabled", "data-type": "switch" });
        box.checked = body.open;
        on.append(box, el("span", { class: "name" }, "include " + name));
        body.append(on);
        fs.append(body);
        fs.classList.add("collapsed");
      } else if (!required && allDefaults(doc, s) && value === undefined) {
        // an optional group the defaults cover: collapsed until wanted
        body = el("details", { "data-group": path });
        body.append(el("summary", {}, name + " (defaults)"));
        fs.append(body);
        fs.classList.add("collapsed");
      } else {
        const unit = isProfile(s) ? groupUnit(s) : null;
        fs.append(el("legend", {}, name + (unit ? " [" + unit + "]" : "")));
      }
      if (s.description) body.append(el("small", { class: "help block" }, helpText(s.description)));
      fields(doc, s, path, value, body, undefined, isProfile(s) ? groupUnit(s) : undefined);
      return fs;
    }
    return leaf(doc, s, path, name, value, required, inherit);
  }

  // ---- lists of objects (loads, operating points) ----------------------------------------

  //: page hooks giving the initial value of a new item of a list, by the list's path
  const newItemHooks = {};

  function onNewItem(path, hook) {
    newItemHooks[path] = hook;
  }

  function list(doc, s, path, name, value) {
    // one block per item (named path.0, path.1, ... as the API names them in its errors),
    // add / remove within minItems..maxItems; redrawn from the collected values on a change
    const item = itemSchema(doc, s);
    const max = s.maxItems !== undefined ? s.maxItems : Infinity;
    const min = s.nullable ? 0 : s.minItems || 0;
    const fs = el("fieldset", { class: "list", "data-list": path, "data-group": path });
    const legend = el("legend", {});
    const title = el("span", {}, name);
    const count = el("span", { class: "count" });
    legend.append(title, " ", count);
    fs.append(legend);
    if (s.description) fs.append(el("small", { class: "help block" }, helpText(s.description)));
    const head = el("div", { class: "leaf list-error" });
    head.append(el("span", { class: "error", "data-error-for": path }));
    fs.append(head);
    const items = el("div", { class: "items" });
    const kinds = isUnion(item) ? Object.keys(item.discriminator.mapping) : null;
    const add = el("button", { type: "button", class: "add", "data-add": path },
      "+ add " + name + " item" + (kinds ? " (" + kinds.join(" / ") + ")" : ""));
    fs.append(items, add);

    function one(i, v) {
      const p = path + "." + i;
      const label = name + " #" + (i + 1);
      let box;
      if (kinds) {
        box = union(doc, item, p, label, v);
      } else if (mapValue(doc, item)) {
        box = map(doc, item, p, label, v);
      } else {
        box = el("fieldset", { class: "group", "data-group": p });
        box.append(el("legend", {}, label));
        if (item.description) box.append(el("small", { class: "help block" }, helpText(item.description)));
        const slot = el("div", { class: "leaf" });
        slot.append(el("span", { class: "error", "data-error-for": p }));
        box.append(slot);
        fields(doc, item, p, v, box);
      }
      box.classList.add("item");
      box.dataset.item = p;
      const remove = el("button", { type: "button", class: "remove", "data-remove": p, title: "remove " + label }, "remove");
      remove.addEventListener("click", () => {
        const current = values();
        current.splice(i, 1);
        draw(current);
      });
      box.querySelector(":scope > legend").append(" ", remove);
      return box;
    }

    function values() {
      return collectList(doc, s, path, fs) || [];
    }

    function draw(vals) {
      items.textContent = "";
      vals.forEach((v, i) => items.append(one(i, v)));
      const n = vals.length;
      count.textContent = "(" + n + (max !== Infinity ? " of at most " + max : "") + ")";
      add.disabled = n >= max;
      for (const b of items.querySelectorAll("[data-remove]")) b.disabled = n <= min;
      fs.dataset.count = String(n);
      fs.dispatchEvent(new CustomEvent("listchange", { bubbles: true, detail: { path, count: n } }));
    }

    add.addEventListener("click", () => {
      const current = values();
      const hook = newItemHooks[path];
      const last = current.length ? JSON.parse(JSON.stringify(current[current.length - 1])) : undefined;
      current.push(hook ? hook(current) : last);
      draw(current);
      const added = items.lastElementChild;
      if (added) {
        const first = added.querySelector("input, select");
        if (first) first.focus();
      }
    });
    const initial = Array.isArray(value) ? value : Array.isArray(s.default) ? s.default : [];
    draw(initial);
    return fs;
  }

  // ---- maps: key -> value (a study's grid, cases, sampled parameters) ---------------------

  function map(doc, s, path, name, value) {
    // one entry per key: the key (e.g. a field path) and the value's own fields, named
    // path.key... as the API names them in its errors ("grid.pipe.L.2",
    // "samples.parameters.pipe.E.sigma"); redrawn from the collected values when a key
    // changes, is added or removed
    const vs = mapValue(doc, s);
    const keyHelp = helpText(s.propertyNames && s.propertyNames.description);
    const max = s.maxProperties !== undefined ? s.maxProperties : Infinity;
    const fs = el("fieldset", { class: "map", "data-map": path, "data-group": path });
    const legend = el("legend", {});
    const count = el("span", { class: "count" });
    legend.append(el("span", {}, name), " ", count);
    fs.append(legend);
    if (s.description) fs.append(el("small", { class: "help block" }, helpText(s.description)));
    const head = el("div", { class: "leaf list-error" });
    head.append(el("span", { class: "error", "data-error-for": path }));
    const entries = el("div", { class: "entries" });
    const add = el("button", { type: "button", class: "add", "data-add": path }, "+ add " + name + " entry");
    fs.append(head, entries, add);

    function one(i, key, v) {
      const p = path + "." + (key || "#" + i);
      const box = el("div", { class: "entry", "data-entry": p });
      const label = el("label", { class: "field map-key", title: keyHelp });
      label.append(el("span", { class: "name" }, "field path"));
      const input = el("input", { "data-map-key": path, value: key || "", placeholder: "e.g. pipe.E", class: "wide" });
      input.addEventListener("change", () => draw(values()));
      label.append(input);
      const keyLeaf = el("div", { class: "leaf" });
      keyLeaf.append(label);
      const remove = el("button", { type: "button", class: "remove", "data-remove": p, title: "remove " + (key || "entry") }, "remove");
      remove.addEventListener("click", () => {
        const current = values();
        current.splice(i, 1);
        draw(current);
      });
      box.append(keyLeaf, remove, node(doc, vs, p, key || "value", v, true));
      return box;
    }

    function values() {
      // [key, value] pairs as typed (an entry without a key too, until it gets one)
      const out = [];
      for (const box of entries.querySelectorAll(":scope > .entry")) {
        const key = box.querySelector("[data-map-key]").value.trim();
        out.push([key, collectNode(doc, vs, box.dataset.entry, box)]);
      }
      return out;
    }

    function draw(pairs) {
      entries.textContent = "";
      pairs.forEach(([k, v], i) => entries.append(one(i, k, v)));
      count.textContent = "(" + pairs.length + (max !== Infinity ? " of at most " + max : "") + ")";
      add.disabled = pairs.length >= max;
      fs.dataset.count = String(pairs.length);
    }

    add.addEventListener("click", () => {
      const current = values();
      const last = current.length ? JSON.parse(JSON.stringify(current[current.length - 1][1] ?? null)) : undefined;
      current.push(["", last === null ? undefined : last]);
      draw(current);
      const added = entries.lastElementChild;
      if (added) added.querySelector("[data-map-key]").focus();
    });
    const initial = value && typeof value === "object" ? value : s.default && typeof s.default === "object" ? s.default : {};
    draw(Object.entries(initial));
    return fs;
  }

  function collectMap(doc, s, path, scope) {
    // the entries with a key, in order; undefined when there are none (not sent)
    const host = scope.matches && scope.matches('[data-map="' + CSS.escape(path) + '"]') ? scope
      : scope.querySelector('[data-map="' + CSS.escape(path) + '"]');
    if (!host) return undefined;
    const vs = mapValue(doc, s);
    const out = {};
    for (const box of host.querySelectorAll(":scope > .entries > .entry")) {
      const key = box.querySelector("[data-map-key]").value.trim();
      const v = collectNode(doc, vs, box.dataset.entry, box);
      if (key !== "" && v !== undefined) out[key] = v;
    }
    return Object.keys(out).length ? out : undefined;
  }

  function collectList(doc, s, path, scope) {
    const host = scope.matches && scope.matches('[data-list="' + CSS.escape(path) + '"]') ? scope
      : scope.querySelector('[data-list="' + CSS.escape(path) + '"]');
    if (!host) return undefined;
    const item = itemSchema(doc, s);
    const out = [];
    for (const box of host.querySelectorAll(":scope > .items > .item")) {
      const p = box.dataset.item;
      out.push(isUnion(item) ? collectNode(doc, item, p, box)
        : mapValue(doc, item) ? collectMap(doc, item, p, box) || {} : collectObject(doc, item, p, box));
    }
    return out;
  }

  function fields(doc, s, prefix, value, host, skip, inherit) {
    const required = new Set(s.required || []);
    for (const [name, sub] of Object.entries(s.properties || {})) {
      if (name === skip || sub.const !== undefined) continue;
      const path = prefix ? prefix + "." + name : name;
      const v = value ? value[name] : undefined;
      host.append(node(doc, sub, path, name, v, required.has(name), inherit));
    }
  }

  function render(host, doc, schema, values) {
    host.textContent = "";
    fields(doc, deref(doc, schema), "", values, host);
  }

  // ---- form -> JSON ----------------------------------------------------------------------

  function numberOrRaw(text) {
    // send what the user typed when it is not a number: the API names the field
    const s = String(text).trim();
    if (s === "") return undefined;
    const x = Number(s);
    return Number.isFinite(x) ? x : s;
  }

  function find(scope, path) {
    const sel = '[name="' + CSS.escape(path) + '"]';
    for (const e of scope.querySelectorAll(sel)) {
      // the input of this scope, not one of a nested hidden kind block
      if (!e.closest(".kind[hidden]") || scope.closest(".kind[hidden]")) return e;
    }
    return null;
  }

  function readLeaf(s, input) {
    if (!input) return undefined;
    const type = input.dataset.type;
    if (type === "boolean") return input.checked;
    if (type === "enum") {
      const raw = input.value;
      if (raw === "" && s.nullable) return null;
      const match = (s.enum || []).find((o) => String(o) === raw);
      return match !== undefined ? match : raw;
    }
    const text = input.value.trim();
    if (text === "") return s.nullable ? null : undefined;
    if (type === "array") return withUnit(input, text.split(/[,\s]+/).filter((t) => t !== "").map(numberOrRaw));
    if (type === "number" || type === "integer") return withUnit(input, numberOrRaw(text));
    return text;
  }

  function collectNode(doc, schema, path, scope) {
    const s = deref(doc, schema);
    if (isUnion(s)) {
      const disc = s.discriminator.propertyName;
      const select = find(scope, path + "." + disc);
      const kind = select.value;
      const block = select.closest("fieldset").querySelector(':scope > .kind[data-kind="' + CSS.escape(kind) + '"]');
      const variant = deref(doc, { $ref: s.discriminator.mapping[kind] });
      return Object.assign({ [disc]: kind }, collectObject(doc, variant, path, block, disc));
    }
    if (itemSchema(doc, s)) {
      // an empty list is left out: its default (none, or null) applies
      const items = collectList(doc, s, path, scope);
      return items && items.length ? items : undefined;
    }
    if (mapValue(doc, s)) return collectMap(doc, s, path, scope);
    if (isObject(s)) {
      const on = s.nullable ? find(scope, path + ".enabled") : null;
      if (on && !on.checked) return undefined;  // switched off: the default (null) applies
      const out = collectObject(doc, s, path, scope);
      return Object.keys(out).length ? out : undefined;
    }
    const v = readLeaf(s, find(scope, path));
    // a nullable field left empty whose default is null: leave it out (the default applies)
    if (v === null && (s.default === null || s.default === undefined)) return undefined;
    return v;
  }

  function collectObject(doc, s, prefix, scope, skip) {
    const out = {};
    for (const [name, sub] of Object.entries(s.properties || {})) {
      if (name === skip || sub.const !== undefined) continue;
      const v = collectNode(doc, sub, prefix ? prefix + "." + name : name, scope);
      if (v !== undefined) out[name] = v;
    }
    return out;
  }

  function collect(host, doc, schema) {
    return collectObject(doc, deref(doc, schema), "", host);
  }

  // ---- the API's errors next to the fields ----------------------------------------------

  function clearErrors(root) {
    for (const e of root.querySelectorAll("[data-error-for]")) e.textContent = "";
    for (const e of root.querySelectorAll(".invalid")) e.classList.remove("invalid");
  }

  function errorSlot(root, field, fallback) {
    // the longest form field that is a prefix of the API's dotted path
    // (e.g. "flow.velocity.coefficients.1" -> "flow.velocity.coefficients"), visible first
    const parts = (field || "").split(".");
    for (let n = parts.length; n > 0; n--) {
      const name = parts.slice(0, n).join(".");
      const slots = [...root.querySelectorAll('[data-error-for="' + CSS.escape(name) + '"]')];
      const slot = slots.find((x) => !x.closest("[hidden]")) || slots[0];
      if (slot) {
        const inputs = [...root.querySelectorAll('[data-field="' + CSS.escape(name) + '"]')];
        return { slot, input: inputs.find((x) => !x.closest("[hidden]")) || inputs[0] || null };
      }
    }
    return { slot: fallback, input: null };
  }

  function showProblem(root, problem, fallback) {
    const errors = problem.errors && problem.errors.length ? problem.errors
      : [{ field: problem.field || null, message: problem.detail || problem.title }];
    for (const e of errors) {
      const { slot, input } = errorSlot(root, e.field, fallback);
      const text = slot === fallback && e.field ? e.field + ": " + e.message : e.message;
      slot.textContent = slot.textContent ? slot.textContent + "; " + text : text;
      if (input) input.classList.add("invalid");
      const details = slot.closest("details");
      if (details) details.open = true;
    }
    return problem.title || "error";
  }

  async function problemOf(response) {
    try {
      return await response.json();
    } catch (e) {
      return { title: response.status + " " + response.statusText };
    }
  }

  // ---- page helpers shared by both pages ------------------------------------------------

  async function post(url, body, form, fallback) {
    // POST JSON; on an error answer, its problem details go next to the fields and null
    // is returned with the problem's title as ``post.title``
    const response = await fetch(url, {
      method: "POST",
      headers: { "Content-Type": "application/json", Accept: "application/json" },
      body: JSON.stringify(body),
    });
    if (response.ok) return { ok: true, body: await response.json() };
    return { ok: false, title: showProblem(form, await problemOf(response), fallback) };
  }

  function showWarnings(list, warnings) {
    list.textContent = "";
    for (const w of warnings || []) list.appendChild(el("li", {}, w));
  }

  function shareLink(link, params) {
    // the page's own URL with ``params`` (key, spec, ...) as its query: a link to this result
    const url = new URL(window.location.href);
    url.search = "";
    for (const [k, v] of Object.entries(params)) {
      if (v !== undefined && v !== null) url.searchParams.set(k, typeof v === "string" ? v : JSON.stringify(v));
    }
    link.href = url.toString();
    link.textContent = params.key.slice(0, 12) + "…";
    window.history.replaceState(null, "", url.toString());
  }

  return {
    deref, requestSchema, render, collect, clearErrors, onNewItem, showProblem, problemOf, show, unitOf,
    showWarnings, shareLink, post, quantityOf, UNIT_CHOICES, helpText,
  };
})();
