"""The static parts of ``index.html``: its HTML template, its style sheet and its script.

:func:`qpbench.bench.html_report.page` fills :data:`TEMPLATE` (``str.format`` fields
``style``, ``plotly``, ``summary``, ``sections``, ``data`` and ``script``). :data:`SCRIPT`
reads the page's data from the ``qpbench-data`` JSON element and draws every interactive
chart and table with Plotly, which the page embeds; the page fetches nothing.
"""

TEMPLATE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>qpbench: what accuracy costs</title>
<style>{style}</style>
<script>{plotly}</script>
</head><body>
<header><h1>qpbench: what accuracy costs</h1><p>{summary}</p>
<nav><a href="#comparison">comparison</a> <a href="#accuracy-cost">accuracy cost</a>
<a href="#wrappers">wrappers</a> <a href="#simulations">whole simulations</a>
<a href="#answer">fastest overall</a>
<a href="#work-precision">work-precision</a>
<a href="#profiles">profiles</a> <a href="#results">table</a> <a href="#problem">one problem</a>
<a href="#friction">friction</a> <a href="#provenance">machine</a></nav></header>
<main>{sections}</main>
<script type="application/json" id="qpbench-data">{data}</script>
<script>{script}</script>
</body></html>
"""

STYLE = """
body { font-family: system-ui, sans-serif; margin: 0 auto; max-width: 1200px; padding: 0 1em;
       color: #222; }
header nav a { margin-right: 0.8em; }
section { margin: 2em 0; }
table { border-collapse: collapse; font-size: 0.85em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.5em; text-align: left; vertical-align: top; }
thead th { background: #f2f2f2; }
table.sortable thead th { cursor: pointer; user-select: none; }
th.sorted-asc::after { content: " \\25B2"; } th.sorted-desc::after { content: " \\25BC"; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.frontier td span { display: block; }
.frontier .time { font-weight: bold; } .digit { color: #a33; }
.comparison td.best { font-weight: bold; background: #eef6ee; } .scroll { overflow-x: auto; }
.comparison .time { white-space: nowrap; }
.small { color: #666; font-size: 0.85em; } .none { color: #888; }
.plot { width: 100%; height: 520px; } .plot.small { height: 380px; }
.controls { margin: 0.5em 0; } .controls label { margin-right: 1em; }
"""

SCRIPT = r"""
(function () {
  "use strict";
  const DATA = JSON.parse(document.getElementById("qpbench-data").textContent);
  const ALL = "all problems", FLOOR = 1e-17, CONFIG = {responsive: true, displaylogo: false};
  const lvl = (a) => a.toExponential(0).replace(/e([+-])(\d)$/, "e$10$2");
  const fmt = (v) => v === null || v === undefined ? "-" : (typeof v === "number" ?
    (Number.isInteger(v) ? String(v) : v.toPrecision(3)) : String(v));
  const logAxis = (title) => ({type: "log", title: {text: title}, exponentformat: "e"});
  function options(select, values, chosen) {
    select.innerHTML = "";
    for (const value of values) {
      const option = document.createElement("option");
      option.value = value; option.textContent = value; select.appendChild(option);
    }
    if (chosen !== undefined) select.value = chosen;
  }
  function families(ds) {
    return [ALL, ...Array.from(new Set(ds.problems.map((p) => p.family))).sort()];
  }

  // work-precision: every answered solve of one family, one trace per pair
  function workPrecision(ds, div, family, visibleKeys) {
    const traces = ds.pairs.map((pair) => ({
      type: "scatter", mode: "markers", name: pair.key, x: [], y: [], customdata: [],
      marker: {size: 6, opacity: 0.75},
      hovertemplate: "solver %{customdata[0]}<br>formulation %{customdata[1]}<br>" +
        "problem %{customdata[2]}<br>level %{customdata[3]}<br>residual %{customdata[4]}<br>" +
        ds.error + " %{customdata[5]}<br>time %{customdata[6]} s<extra></extra>"}));
    const inFamily = (i) => family === ALL || ds.problems[ds.problem[i]].family === family;
    let hasError = false;
    for (let i = 0; i < ds.pair.length; i++) {
      if (inFamily(i) && ds.v_error[i] !== null && ds.time[i] !== null) { hasError = true; break; }
    }
    const errorName = hasError ? ds.error : "residual";
    for (let i = 0; i < ds.pair.length; i++) {
      if (!inFamily(i) || ds.time[i] === null || ds.residual[i] === null) continue;
      const y = hasError ? ds.v_error[i] : ds.residual[i];
      if (y === null) continue;
      const pair = ds.pairs[ds.pair[i]], trace = traces[ds.pair[i]];
      trace.x.push(Math.max(ds.time[i], 1e-9));
      trace.y.push(Math.max(y, FLOOR));
      trace.customdata.push([pair.solver, pair.formulation, ds.problems[ds.problem[i]].name,
        lvl(ds.levels[ds.level[i]]), fmt(ds.residual[i]), fmt(ds.v_error[i]), fmt(ds.time[i])]);
    }
    const shown = traces.filter((t) => t.x.length > 0);
    for (const trace of shown) {
      trace.visible = !visibleKeys || visibleKeys.has(trace.name) ? true : "legendonly";
    }
    Plotly.newPlot(div, shown, {
      title: {text: "Work-precision, " + family}, hovermode: "closest",
      xaxis: logAxis("time_s [s]"), yaxis: logAxis(errorName),
      legend: {font: {size: 10}}, margin: {t: 40}}, CONFIG);
  }
  // the pairs drawn at first: the family's frontier and the most reliable few
  function firstPairs(family) {
    const keys = new Set();
    const rows = (DATA.table || []).filter((r) => r[0] === family);
    for (const row of DATA.frontierRows || []) {
      if (row.family === family && row.pair) keys.add(row.pair);
    }
    const tightest = Math.min(...rows.map((r) => r[4]));
    rows.filter((r) => r[4] === tightest)
      .sort((a, b) => (b[6] - a[6]) || (a[7] - b[7])).slice(0, 5)
      .forEach((r) => keys.add(r[1]));
    return keys;
  }

  // what accuracy costs: each growing pair's time relative to the loosest level
  if (DATA.accuracy_cost) {
    const cost = DATA.accuracy_cost, names = cost.levels.map(lvl);
    Plotly.newPlot("accuracy-cost-plot", cost.pairs.map((pair, index) => ({
      type: "scatter", mode: "lines+markers", name: pair.key, x: names, y: pair.relative,
      visible: index < 12 ? true : "legendonly",
      hovertemplate: pair.key + "<br>level %{x}<br>%{y:.3g} x the time at " + names[0] +
        "<extra></extra>"})), {
      title: {text: "What accuracy costs: time relative to " + names[0]},
      xaxis: {type: "category", categoryorder: "array", categoryarray: names,
              title: {text: "accuracy level"}},
      yaxis: logAxis("time relative to " + names[0]), legend: {font: {size: 10}},
      margin: {t: 40}}, CONFIG);
  }

  if (DATA.main) {
    const ds = DATA.main;
    DATA.frontierRows = [];
    for (const cell of document.querySelectorAll("#frontier tbody tr")) {
      const family = cell.querySelector("th").textContent;
      for (const code of cell.querySelectorAll("code")) {
        DATA.frontierRows.push({family: family, pair: code.textContent});
      }
    }
    // frontier time against level, one line per family
    const byFamily = new Map();
    for (const row of DATA.frontier) {
      if (!byFamily.has(row.family)) byFamily.set(row.family, {x: [], y: []});
      if (row.time !== null) { byFamily.get(row.family).x.push(lvl(row.level));
                               byFamily.get(row.family).y.push(row.time); }
    }
    const levelNames = ds.levels.map(lvl);
    Plotly.newPlot("frontier-plot", Array.from(byFamily, ([family, xy]) => ({
      type: "scatter", mode: "lines+markers", name: family, x: xy.x, y: xy.y,
      line: family === ALL ? {width: 4, color: "#000"} : {width: 1.5},
      hovertemplate: family + "<br>level %{x}<br>SGM %{y:.3g} s<extra></extra>"})), {
      title: {text: "Time of the fastest pair that reaches each level"},
      xaxis: {type: "category", categoryorder: "array", categoryarray: levelNames,
              title: {text: "accuracy level"}},
      yaxis: logAxis("SGM time [s]"), legend: {font: {size: 10}}, margin: {t: 40}}, CONFIG);

    const wpSelect = document.getElementById("wp-family");
    options(wpSelect, families(ds), ALL);
    const drawWp = () => workPrecision(ds, "wp", wpSelect.value, firstPairs(wpSelect.value));
    wpSelect.addEventListener("change", drawWp);
    drawWp();
    const setAll = (visible) => {
      const div = document.getElementById("wp");
      Plotly.restyle(div, {visible: visible}, div.data.map((_, i) => i));
    };
    document.getElementById("wp-all").addEventListener("click", () => setAll(true));
    document.getElementById("wp-none").addEventListener("click", () => setAll("legendonly"));

    DATA.profiles.forEach((profile, index) => {
      Plotly.newPlot("profile-" + index, profile.curves.map((curve) => ({
        type: "scatter", mode: "lines", name: curve.key, x: profile.taus, y: curve.values,
        line: {shape: "hv"}, visible: curve.visible ? true : "legendonly",
        hovertemplate: curve.key + "<br>tau %{x:.3g}<br>share %{y:.2f}<extra></extra>"})), {
        title: {text: "Performance profile at " + lvl(profile.level) + " (" +
                profile.problems + " problems)"},
        xaxis: logAxis("tau (time / fastest time on the problem)"),
        yaxis: {range: [0, 1.02], title: {text: "share of problems solved within tau"}},
        legend: {font: {size: 10}}, margin: {t: 40}}, CONFIG);
    });

    // the results table: sort on header click, filter by selects and text
    const COLUMNS = ["family", "pair", "formulation", "backend", "level", "solves",
                     "success", "SGM time [s]", "median residual"];
    const table = document.getElementById("results-table");
    const head = table.querySelector("thead"), body = table.querySelector("tbody");
    const MAX_ROWS = 400;
    let sortColumn = null, sortDirection = 1;
    head.innerHTML = "<tr>" + COLUMNS.map((c, i) => "<th data-col='" + i + "'>" + c + "</th>")
      .join("") + "</tr>";
    const selects = Array.from(document.querySelectorAll("#filters select"));
    for (const select of selects) {
      const column = Number(select.dataset.filter);
      let values = Array.from(new Set(DATA.table.map((r) => r[column])));
      values = column === 4 ? values.sort((a, b) => b - a).map(lvl) : values.sort();
      options(select, ["(any)", ...values], "(any)");
      select.addEventListener("change", render);
    }
    const pairFilter = document.getElementById("pair-filter");
    pairFilter.addEventListener("input", render);
    function cellText(row, column) {
      if (column === 4) return lvl(row[4]);
      if (column === 6) return row[6] === null ? "-" : (100 * row[6]).toFixed(1) + "%";
      return fmt(row[column]);
    }
    function render() {
      const text = pairFilter.value.trim().toLowerCase();
      let rows = DATA.table.filter((row) => selects.every((select) => {
        const column = Number(select.dataset.filter);
        return select.value === "(any)" ||
          (column === 4 ? lvl(row[4]) : String(row[column])) === select.value;
      }) && (!text || row[1].toLowerCase().includes(text)));
      if (sortColumn !== null) {
        const c = sortColumn;
        rows = rows.slice().sort((a, b) => {
          const x = a[c], y = b[c];
          if (x === y) return 0;
          if (x === null) return 1;
          if (y === null) return -1;
          return (typeof x === "number" ? x - y : String(x).localeCompare(String(y))) *
            sortDirection;
        });
      }
      body.innerHTML = rows.slice(0, MAX_ROWS).map((row) => "<tr>" + row.map((_, c) =>
        "<td" + (c >= 4 ? " class='num'" : "") + ">" + cellText(row, c)
          .replace(/&/g, "&amp;").replace(/</g, "&lt;") + "</td>").join("") + "</tr>").join("");
      document.getElementById("table-count").textContent = rows.length > MAX_ROWS ?
        "showing the first " + MAX_ROWS + " of " + rows.length + " rows: filter to see others" :
        rows.length + " rows";
    }
    for (const th of head.querySelectorAll("th")) {
      th.addEventListener("click", () => {
        const column = Number(th.dataset.col);
        sortDirection = sortColumn === column ? -sortDirection : 1;
        sortColumn = column;
        for (const other of head.querySelectorAll("th")) other.className = "";
        th.className = sortDirection > 0 ? "sorted-asc" : "sorted-desc";
        render();
      });
    }
    render();

    // one problem: every pair's residual against time, one point per level
    const problemSelect = document.getElementById("problem-select");
    options(problemSelect, ds.problems.map((p) => p.name), ds.problems[0].name);
    function drawProblem() {
      const index = ds.problems.findIndex((p) => p.name === problemSelect.value);
      const traces = new Map();
      for (let i = 0; i < ds.pair.length; i++) {
        if (ds.problem[i] !== index || ds.time[i] === null || ds.residual[i] === null) continue;
        const pair = ds.pairs[ds.pair[i]];
        if (!traces.has(pair.key)) traces.set(pair.key, {points: [], solved: 0, time: 0});
        const entry = traces.get(pair.key);
        entry.points.push([ds.level[i], ds.time[i], ds.residual[i], ds.v_error[i], ds.success[i]]);
        if (ds.success[i] && ds.level[i] === ds.levels.length - 1) { entry.solved = 1;
                                                                     entry.time = ds.time[i]; }
      }
      const ranked = Array.from(traces.entries()).filter(([, e]) => e.solved)
        .sort((a, b) => a[1].time - b[1].time).slice(0, 12).map(([key]) => key);
      const first = new Set(ranked.length ? ranked : Array.from(traces.keys()).slice(0, 12));
      const data = Array.from(traces, ([key, entry]) => {
        entry.points.sort((a, b) => a[0] - b[0]);
        return {type: "scatter", mode: "lines+markers", name: key,
          visible: first.has(key) ? true : "legendonly",
          x: entry.points.map((p) => Math.max(p[1], 1e-9)),
          y: entry.points.map((p) => Math.max(p[2], FLOOR)),
          customdata: entry.points.map((p) => [lvl(ds.levels[p[0]]), fmt(p[2]), fmt(p[3]),
                                               fmt(p[1]), p[4] ? "solved" : "not solved"]),
          hovertemplate: key + "<br>level %{customdata[0]} (%{customdata[4]})<br>residual " +
            "%{customdata[1]}<br>v_error %{customdata[2]}<br>time %{customdata[3]} s" +
            "<extra></extra>"};
      });
      Plotly.newPlot("problem-plot", data, {
        title: {text: "Problem " + problemSelect.value + " (" + ds.problems[index].family + ")"},
        hovermode: "closest", xaxis: logAxis("time_s [s]"), yaxis: logAxis("residual"),
        legend: {font: {size: 10}}, margin: {t: 40}}, CONFIG);
    }
    problemSelect.addEventListener("change", drawProblem);
    drawProblem();
  }

  if (DATA.friction) {
    const fds = DATA.friction, select = document.getElementById("fwp-family");
    options(select, families(fds), ALL);
    const draw = () => workPrecision(fds, "fwp", select.value, null);
    select.addEventListener("change", draw);
    draw();
  }
})();
"""
