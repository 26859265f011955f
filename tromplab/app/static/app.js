// The page of `tromplab app`. Every text that comes from a file or from the server is put into the
// document with textContent or as an option's text, never as HTML; figure labels are escaped for plotly.
"use strict";

const PAGE_HEADERS = { "x-tromplab-page": "1" };
const state = { upload: null, options: [], page: null, experiment: 0, polling: null, sort: { column: null, down: false } };
//: The button's word for each command's run.
const RUN_WORDS = { "tromplab fit": "Fit", "tromplab density fit": "Fit", "tromplab circuit": "Run", "tromplab circuit design": "Run", "tromplab trend": "Run" };
const DOWNLOAD_LINKS = { "results.zip": "download-zip", "report.html": "download-report", "results.xlsx": "download-xlsx",
  "trend_report.html": "download-trend-report" };

function $(id) { return document.getElementById(id); }

function element(tag, text, className) {
  const made = document.createElement(tag);
  if (text !== undefined && text !== null) made.textContent = String(text);
  if (className) made.className = className;
  return made;
}

function show(id, visible) { $(id).hidden = !visible; }

function say(id, message) {
  $(id).textContent = message || "";
  show(id, Boolean(message));
}

// plotly reads a few HTML-like tags in labels: names from a file are escaped so they show as written
function plotlyText(text) {
  return String(text).replace(/&/g, "&amp;").replace(/</g, "&lt;").replace(/>/g, "&gt;");
}

function formatNumber(value, digits) {
  if (value === null || value === undefined) return "";
  if (typeof value === "boolean") return value ? "yes" : "no";
  if (typeof value !== "number") return String(value);
  if (Number.isInteger(value)) return String(value);
  return String(Number(value.toPrecision(digits || 4)));
}

async function api(path, options) {
  const response = await fetch(path, Object.assign({ credentials: "same-origin" }, options || {}));
  let body = {};
  try { body = await response.json(); } catch (error) { body = { error: `the server answered ${response.status}` }; }
  if (!response.ok && !body.error) body.error = `the server answered ${response.status}`;
  return body;
}

async function post(path, data, extra) {
  const headers = Object.assign({}, PAGE_HEADERS, extra && extra.headers);
  const body = extra && extra.body !== undefined ? extra.body : JSON.stringify(data || {});
  if (!(extra && extra.body !== undefined)) headers["content-type"] = "application/json";
  return api(path, { method: "POST", headers, body });
}

// -- the table ---------------------------------------------------------------------------------
async function startSession() {
  const session = await api("/api/session");
  const select = $("example-select");
  for (const [name, label] of Object.entries(session.examples || {})) {
    const option = element("option", `${name}: ${label}`);
    option.value = name;
    select.appendChild(option);
  }
  state.maxUpload = session.max_upload;
}

async function sendFiles(files) {
  say("table-error", "");
  for (const file of files) {  // one after the other: a circuit's flowsheet and survey pair up on the server
    if (state.maxUpload && file.size > state.maxUpload) {
      say("table-error", `${file.name}: larger than the upload limit of ${state.maxUpload / 1048576} MiB`);
      return;
    }
    const described = await post(`/api/upload?name=${encodeURIComponent(file.name)}`, null,
      { body: file, headers: { "content-type": "application/octet-stream" } });
    showTable(described);
    if (described.error) return;
  }
}

async function useExample() {
  const name = $("example-select").value;
  showTable(await post(`/api/example?name=${encodeURIComponent(name)}`));
}

function showTable(described) {
  show("results-section", false);
  say("run-error", "");
  show("command-line", false);
  if (described.error && !described.name) {
    say("table-error", described.error);
    return;
  }
  state.upload = described;
  show("table-info", true);
  $("file-name").textContent = described.name;
  const sheets = described.sheets || [];
  const sheetSelect = $("sheet-select");
  sheetSelect.replaceChildren(...sheets.map((sheet) => {
    const option = element("option", sheet);
    option.value = sheet;
    option.selected = sheet === described.sheet;
    return option;
  }));
  show("sheet-row", sheets.length > 0);
  const pair = described.circuit || {};
  const circuit = described.kind && (described.kind.kind === "flowsheet" || described.kind.kind === "survey");
  $("pair-flowsheet").textContent = pair.flowsheet || "(drop it too)";
  $("pair-survey").textContent = pair.survey || "(drop it too)";
  show("circuit-pair", Boolean(circuit));
  if (described.error) {
    $("file-kind").textContent = "";
    say("table-error", described.error);
    show("options-section", false);
    return;
  }
  say("table-error", "");
  const kind = described.kind;
  $("file-kind").textContent = `(${kind.label})`;
  if (!kind.runs_here) {
    say("table-error", `This file holds ${kind.label}: the page does not run that yet; on the command line: ${kind.command} ${described.stored_as} ...`);
    show("options-section", false);
    return;
  }
  state.forms = described.forms || { [kind.command]: described.options };
  const commandSelect = $("command-select");
  commandSelect.replaceChildren(...Object.keys(state.forms).map((command) => {
    const option = element("option", command);
    option.value = command;
    return option;
  }));
  show("command-row", Object.keys(state.forms).length > 1);
  chooseCommand(kind.command);
  show("options-section", true);
}

function chooseCommand(command) {
  state.command = command;
  $("command-select").value = command;
  $("options-command").textContent = command;
  $("options-help").textContent = `${command} -h`;
  $("run-button").textContent = RUN_WORDS[command] || "Run";
  buildForm(state.forms[command]);
}

async function chooseSheet() {
  showTable(await post("/api/sheet", { sheet: $("sheet-select").value }));
}

// -- the options, from the command line's declarations -------------------------------------------
function buildForm(options) {
  const form = $("options-form");
  form.replaceChildren();
  state.options = options;
  const groups = new Map();
  for (const option of options) {
    if (!groups.has(option.group)) {
      const fieldset = element("fieldset");
      fieldset.appendChild(element("legend", option.group));
      groups.set(option.group, fieldset);
      form.appendChild(fieldset);
    }
    groups.get(option.group).appendChild(optionRow(option));
  }
}

function optionRow(option) {
  const row = element("div", null, "option");
  const id = `option-${option.dest}`;
  const label = element("label", option.flag);
  label.htmlFor = id;
  let input;
  if (option.widget === "flag") {
    input = element("input");
    input.type = "checkbox";
  } else if (option.widget === "choice") {
    input = element("select");
    if (option.default === null) input.appendChild(element("option", "(not given)"));
    for (const choice of option.choices) {
      const item = element("option", choice);
      item.value = choice;
      item.selected = choice === option.default;
      input.appendChild(item);
    }
  } else {
    input = element("input");
    input.type = "text";
    input.placeholder = option.default === null ? "(not given)" : option.default;
    input.value = option.default === null ? "" : option.default;
  }
  input.id = id;
  input.name = option.dest;
  input.dataset.dest = option.dest;
  row.append(label, input, element("span", option.help, "help"));
  return row;
}

function formValues() {
  const values = {};
  for (const option of state.options) {
    const input = $(`option-${option.dest}`);
    if (option.widget === "flag") {
      if (input.checked) values[option.dest] = true;
    } else if (option.widget === "choice") {
      if (input.selectedIndex >= 0 && input.options[input.selectedIndex].value !== "(not given)") values[option.dest] = input.value;
    } else if (input.value.trim() !== "" && input.value !== (option.default || "")) {
      values[option.dest] = input.value.trim();
    }
  }
  return values;
}

// -- runs ---------------------------------------------------------------------------------------
async function run() {
  say("run-error", "");
  show("results-section", false);
  const sheets = (state.upload && state.upload.sheets) || [];
  const started = await post("/api/run", { options: formValues(), sheet: sheets.length ? $("sheet-select").value : null,
    command: state.command });
  if (started.error) {
    say("run-error", started.error);
    return;
  }
  const commands = [started.command, started.report_command].filter(Boolean).map((command) => command.join(" "));
  $("command-line").textContent = `Same as: ${commands.join("  and  ")}`;
  show("command-line", true);
  setRunning(true);
  poll();
}

function setRunning(running) {
  $("run-button").disabled = running;
  $("cancel-button").disabled = !running;
  show("progress-box", running);
}

async function poll() {
  clearTimeout(state.polling);
  const job = await api("/api/job");
  if (job.state === "running") {
    const progress = job.progress || {};
    const bar = $("progress-bar");
    if (progress.total) { bar.max = progress.total; bar.value = progress.done; } else { bar.removeAttribute("value"); }
    $("progress-text").textContent = `${progress.phase || "starting"}${progress.total ? ` ${progress.done}/${progress.total}` : ""}`;
    state.polling = setTimeout(poll, 400);
    return;
  }
  setRunning(false);
  if (job.state === "failed") say("run-error", job.message);
  else if (job.state === "cancelled") say("run-error", "Cancelled: nothing was kept.");
  else if (job.state === "done") showResults(job.page, job.downloads || []);
  else if (job.error) say("run-error", job.error);
}

async function cancel() {
  clearTimeout(state.polling);
  await post("/api/cancel");
  setRunning(false);
  say("run-error", "Cancelled: nothing was kept.");
}

// -- results ------------------------------------------------------------------------------------
function showResults(page, downloads) {
  state.page = page;
  state.experiment = 0;
  state.sort = { column: null, down: false };
  for (const [name, id] of Object.entries(DOWNLOAD_LINKS)) show(id, downloads.includes(name));
  show("fit-results", page.view === "fit");
  show("circuit-results", page.view === "circuit");
  show("trend-results", page.view === "trend");
  showWarnings(page.warnings);
  if (page.view === "circuit") { show("results-section", true); showCircuit(page); return; }
  if (page.view === "trend") { show("results-section", true); showTrend(page); return; }
  const axes = page.axes;
  const unit = axes.unit ? ` ${axes.unit}` : "";
  $("best-list").replaceChildren(...page.experiments.slice(0, 20).map((experiment) => {
    const best = experiment.best;
    let text = `${experiment.name}: no formula could be fitted`;
    if (best) {
      text = `${experiment.name}: ${axes.best} ${best.formula}, ${axes.cut} = ${formatNumber(best.d50, 3)}${unit}`;
      const tied = best.tied.map((other) => `${other.formula} (${axes.cut} = ${formatNumber(other.d50, 3)})`);
      if (tied.length) text += ` (rank ${formatNumber(best.rank)} tied with ${tied.join(", ")}; the library takes the lowest sum of squares among them)`;
    }
    return element("li", text);
  }));
  const select = $("experiment-select");
  select.replaceChildren(...page.experiments.map((experiment, index) => {
    const option = element("option", experiment.name);
    option.value = String(index);
    return option;
  }));
  if (page.ranking) fillTable($("ranking-table"), page.ranking, null);
  show("ranking-part", Boolean(page.ranking));
  show("results-section", true);
  drawOverview(page);
  showExperiment();
}

function showExperiment() {
  const page = state.page;
  const experiment = page.experiments[state.experiment];
  if (!experiment) return;
  fillTable($("fits-table"), experiment.table, experiment.best && experiment.best.formula);
  if (experiment.intervals) fillTable($("intervals-table"), experiment.intervals, experiment.best && experiment.best.formula);
  else $("intervals-table").replaceChildren();
  show("intervals-hint", !experiment.intervals);
  $("verdicts").replaceChildren(...experiment.verdicts.map((verdict) => element("li", verdict)));
  show("intervals-part", experiment.cannot_tell !== null);  // tromplab density fit: its intervals are columns of the ranked table
  if (experiment.cannot_tell === null) { drawFigure(experiment, page); return; }
  const cannot = experiment.cannot_tell.map((item) => element("li", `${item.formulas.join(", ")}: ${item.text}`));
  $("cannot-tell").replaceChildren(...(cannot.length ? cannot : [element("li", "Nothing: every fitted quantity has its interval where intervals were asked for (--ci).")]));
  drawFigure(experiment, page);
}

function tiedRanks(table) {
  const at = table.columns.indexOf("rank");
  const counts = new Map();
  if (at < 0) return counts;
  for (const row of table.rows) counts.set(row[at], (counts.get(row[at]) || 0) + 1);
  return counts;
}

function fillTable(tableElement, table, best) {
  tableElement.replaceChildren();
  const head = element("thead");
  const headRow = element("tr");
  table.columns.forEach((column, index) => {
    const cell = element("th", column);
    cell.scope = "col";
    cell.addEventListener("click", () => sortTable(tableElement, table, best, index));
    headRow.appendChild(cell);
  });
  head.appendChild(headRow);
  const body = element("tbody");
  const ties = tiedRanks(table);
  const rankAt = table.columns.indexOf("rank");
  const formulaAt = table.columns.indexOf("formula");
  const adequateAt = table.columns.indexOf("adequate");
  for (const row of table.rows) {
    const line = element("tr");
    if (best && row[formulaAt] === best) line.classList.add("best-row");
    if (adequateAt >= 0 && row[adequateAt] === false) line.classList.add("inadequate");
    row.forEach((value, index) => {
      const cell = element("td", formatNumber(value));
      if (typeof value === "string") cell.className = "text";
      if (index === rankAt && value !== null && ties.get(value) > 1) cell.appendChild(element("span", " tied", "tie"));
      line.appendChild(cell);
    });
    body.appendChild(line);
  }
  tableElement.append(head, body);
}

function sortTable(tableElement, table, best, index) {
  const down = state.sort.column === index ? !state.sort.down : false;
  state.sort = { column: index, down };
  const rows = [...table.rows].sort((a, b) => {
    const x = a[index], y = b[index];
    if (x === y) return 0;
    if (x === null) return 1;
    if (y === null) return -1;
    const order = typeof x === "number" && typeof y === "number" ? x - y : String(x).localeCompare(String(y));
    return down ? -order : order;
  });
  fillTable(tableElement, { columns: table.columns, rows }, best);
  tableElement.querySelectorAll("th")[index].textContent += down ? " ▼" : " ▲";
}

function showWarnings(groups) {
  const box = $("warnings");
  box.replaceChildren();
  if (!groups.length) {
    box.appendChild(element("p", "No warnings."));
    return;
  }
  for (const group of groups) {
    const details = element("details");
    const summary = element("summary");
    if (group.count !== null) summary.appendChild(element("span", `${group.count}× `, "warning-count"));
    summary.appendChild(element("span", `[${group.kind}] ${group.text}`));
    details.appendChild(summary);
    if (group.where.length) details.appendChild(element("p", `where: ${group.where.join("; ")}`));
    box.appendChild(details);
  }
}

function drawFigure(experiment, page) {
  if (typeof Plotly === "undefined") return;
  const traces = [];
  for (const curve of experiment.curves) {
    if (curve.band) {
      traces.push({ x: curve.size, y: curve.band.low, mode: "lines", line: { width: 0 }, hoverinfo: "skip", showlegend: false });
      traces.push({ x: curve.size, y: curve.band.high, mode: "lines", line: { width: 0 }, fill: "tonexty",
        fillcolor: "rgba(90,90,90,0.2)", name: `95 % band, ${plotlyText(curve.formula)}`, hoverinfo: "skip" });
    }
  }
  for (const curve of experiment.curves) {
    traces.push({ x: curve.size, y: curve.partition, mode: "lines", name: plotlyText(curve.formula) + (curve.best ? " (best)" : ""),
      line: { width: curve.best ? 4 : 1.5, dash: curve.adequate === false ? "dot" : "solid" }, opacity: curve.adequate === false ? 0.5 : 1 });
  }
  if (experiment.points) {
    traces.push({ x: experiment.points.size, y: experiment.points.partition, mode: "markers", name: "measured",
      marker: { size: 9, color: "black" } });
  }
  const layout = {
    title: { text: plotlyText(experiment.name) },
    xaxis: { title: { text: plotlyText(page.axes.x) }, type: page.axes.log_x ? "log" : "linear" },
    yaxis: { title: { text: plotlyText(page.axes.y) }, range: [-0.03, 1.03] },
    margin: { t: 40 }, hovermode: "closest",
  };
  Plotly.react($("figure"), traces, layout, { displaylogo: false, responsive: true });
}

function drawOverview(page) {
  const fitted = page.experiments.filter((experiment) => experiment.best);
  show("overview-part", fitted.length > 1 && typeof Plotly !== "undefined");
  if (fitted.length < 2 || typeof Plotly === "undefined") return;
  const order = fitted.map((experiment, index) => index + 1);
  const hover = fitted.map((experiment) => plotlyText(`${experiment.name}: ${experiment.best.formula}`));
  const traces = [
    { x: order, y: fitted.map((e) => e.best.d50), text: hover, mode: "lines+markers", name: plotlyText(page.axes.cut),
      hoverinfo: "text+y", line: { width: 3 }, marker: { size: 10 } },
    { x: order, y: fitted.map((e) => e.best.ep), text: hover, mode: "lines+markers", name: "Ep (right axis)", yaxis: "y2",
      hoverinfo: "text+y", line: { dash: "dot" }, marker: { symbol: "square", size: 8 } },
  ];
  const unit = page.axes.unit ? ` (${plotlyText(page.axes.unit)})` : "";
  const layout = {
    xaxis: { title: { text: "experiment, in the file's order" }, dtick: Math.max(1, Math.ceil(fitted.length / 12)) },
    yaxis: { title: { text: plotlyText(page.axes.cut) + unit } },
    yaxis2: { title: { text: `Ep${unit}` }, overlaying: "y", side: "right" },
    margin: { t: 20 }, legend: { orientation: "h" },
  };
  Plotly.react($("overview"), traces, layout, { displaylogo: false, responsive: true });
}

// -- a circuit: the flowsheet with its flows, the summary, the folder's tables ------------------------
function showCircuit(page) {
  $("flowsheet-heading").textContent = page.flowsheet_title || "The flowsheet with its reconciled flows";
  $("circuit-summary").textContent = page.summary.join("\n");
  const select = $("circuit-table-select");
  select.replaceChildren(...page.tables.map((table, index) => {
    const option = element("option", table.name);
    option.value = String(index);
    return option;
  }));
  showCircuitTable();
  drawFlowsheet(page.flowsheet);
}

function showCircuitTable() {
  const table = state.page.tables[Number($("circuit-table-select").value || 0)];
  if (!table) return;
  const more = table.rows_in_file > table.table.rows.length ? ` (the first ${table.table.rows.length} of ${table.rows_in_file} rows; the file has all)` : "";
  $("circuit-table-what").textContent = `${table.what}${more}`;
  state.sort = { column: null, down: false };
  fillTable($("circuit-table"), table.table, null);
}

function flowText(value, sd) {
  if (value === null || value === undefined) return "not measured";
  return sd === null || sd === undefined ? formatNumber(value, 4) : `${formatNumber(value, 4)} ± ${formatNumber(sd, 2)}`;
}

function streamHover(stream) {
  const lines = [`<b>${plotlyText(stream.name)}</b>`, `reconciled ${flowText(stream.reconciled, stream.reconciled_sd)}`,
    `measured ${flowText(stream.measured, stream.measured_sd)}`];
  for (const suspect of stream.suspects) {
    lines.push(`suspect: ${plotlyText(suspect.measurement)} (test ${formatNumber(suspect.test, 3)}, gross error ${formatNumber(suspect.gross_error, 3)})`);
  }
  if (stream.largest_test && !stream.suspects.length) {
    lines.push(`largest test: ${plotlyText(stream.largest_test.measurement)} (${formatNumber(stream.largest_test.test, 3)})`);
  }
  return lines.join("<br>");
}

function drawFlowsheet(sheet) {
  if (typeof Plotly === "undefined") return;
  const traces = [];
  const annotations = [];
  const labels = { x: [], y: [], text: [], hovertext: [], color: [] };
  for (const stream of sheet.streams) {
    const suspect = stream.suspects.length > 0;
    const color = suspect ? "#c62828" : (stream.path.x.length > 2 ? "#b35900" : "#555555");
    const xs = [...stream.path.x];
    const ys = [...stream.path.y];
    const n = xs.length;
    if (stream.to) {  // the arrow stops short of the unit's box
      const dx = xs[n - 1] - xs[n - 2], dy = ys[n - 1] - ys[n - 2], length = Math.hypot(dx, dy) || 1;
      xs[n - 1] -= 0.35 * dx / length;
      ys[n - 1] -= 0.35 * dy / length;
    }
    traces.push({ x: xs, y: ys, mode: "lines", line: { color, width: suspect ? 4 : 2 }, hoverinfo: "skip", showlegend: false });
    annotations.push({ x: xs[n - 1], y: ys[n - 1], ax: xs[n - 2], ay: ys[n - 2], xref: "x", yref: "y", axref: "x", ayref: "y",
      showarrow: true, arrowhead: 2, arrowsize: 1.3, arrowwidth: suspect ? 3 : 1.5, arrowcolor: color, text: "" });
    const middle = Math.floor((n - 1) / 2);  // the label on the middle segment
    labels.x.push((xs[middle] + xs[middle + 1]) / 2);
    labels.y.push((ys[middle] + ys[middle + 1]) / 2);
    labels.text.push(`${plotlyText(stream.name)}<br>${flowText(stream.reconciled, stream.reconciled_sd)}`);
    labels.hovertext.push(streamHover(stream));
    labels.color.push(color);
  }
  traces.push({ x: labels.x, y: labels.y, text: labels.text, hovertext: labels.hovertext, hoverinfo: "text", mode: "markers+text",
    textposition: "top center", textfont: { size: 11 }, marker: { size: 9, color: labels.color }, name: "streams", showlegend: false });
  traces.push({ x: sheet.nodes.map((node) => node.x), y: sheet.nodes.map((node) => node.y), mode: "markers+text",
    text: sheet.nodes.map((node) => plotlyText(node.name)), textposition: "bottom center",
    hovertext: sheet.nodes.map((node) => `${plotlyText(node.name)} (${plotlyText(node.kind)})`), hoverinfo: "text",
    marker: { symbol: "square", size: 30, color: "#dfe9f7", line: { color: "#2a6edb", width: 2 } }, name: "units", showlegend: false });
  const xs = [...sheet.nodes.map((node) => node.x), ...sheet.streams.flatMap((stream) => stream.path.x)];
  const ys = [...sheet.nodes.map((node) => node.y), ...sheet.streams.flatMap((stream) => stream.path.y)];
  const hidden = { showgrid: false, zeroline: false, showticklabels: false };
  const xaxis = Object.assign({ range: [Math.min(...xs) - 0.8, Math.max(...xs) + 0.8] }, hidden);
  const yaxis = Object.assign({ range: [Math.min(...ys) - 0.5, Math.max(...ys) + 0.8] }, hidden);  // room for the labels above
  const layout = { xaxis, yaxis, annotations, margin: { t: 20, l: 20, r: 20, b: 20 }, hovermode: "closest",
    title: { text: sheet.basis ? plotlyText(`flows relative to ${sheet.basis}`) : "" } };
  Plotly.react($("flowsheet"), traces, layout, { displaylogo: false, responsive: true });
}

// -- a trend: the control charts and the tables ------------------------------------------------------
function showTrend(page) {
  const base = page.surveys.filter((name, index) => page.baseline[index]);
  $("trend-summary").textContent = `Formula ${page.formula} fitted to each of ${page.surveys.length} surveys; baseline ${base[0]} to ${base[base.length - 1]} (${base.length} surveys); intervals at ${formatNumber(100 * page.level, 3)} %; change flags at alpha ${formatNumber(page.alpha)}. Change points: ${page.change_points.length ? page.change_points.join(", ") : "none"}.`;
  state.sort = { column: null, down: false };
  fillTable($("trend-flags"), page.flags, null);
  fillTable($("trend-table"), page.table, null);
  const box = $("trend-charts");
  box.replaceChildren(...page.charts.map((chart) => {
    const holder = element("div", null, "figure chart");
    holder.id = `trend-chart-${chart.quantity}`;
    holder.setAttribute("aria-label", `control chart of ${chart.quantity}`);
    return holder;
  }));
  if (typeof Plotly === "undefined") return;
  page.charts.forEach((chart) => drawControlChart(page, chart));
}

function drawControlChart(page, chart) {
  const names = page.surveys.map((name) => plotlyText(name));
  const colors = chart.value.map((value, index) => (page.baseline[index] ? "#8a8a8a" : chart.alarm[index] ? "#c62828" : "#2a6edb"));
  const above = chart.value.map((value, index) => (value === null || chart.high[index] === null ? null : chart.high[index] - value));
  const below = chart.value.map((value, index) => (value === null || chart.low[index] === null ? null : value - chart.low[index]));
  const traces = [
    { x: page.dates, y: chart.value, text: names, mode: "markers", name: `${chart.quantity} with its interval`, hoverinfo: "text+x+y",
      marker: { size: 9, color: colors }, error_y: { type: "data", symmetric: false, array: above, arrayminus: below, color: "#999" } },
    { x: page.dates, y: chart.ewma, mode: "lines", name: "EWMA", line: { color: "#1d1d1f", width: 2 }, hoverinfo: "x+y" },
    { x: page.dates, y: chart.ewma_low, mode: "lines", name: "EWMA limits", line: { color: "#c62828", dash: "dash" }, hoverinfo: "x+y" },
    { x: page.dates, y: chart.ewma_high, mode: "lines", showlegend: false, line: { color: "#c62828", dash: "dash" }, hoverinfo: "x+y" },
  ];
  const changed = page.changed.map((flag, index) => (flag ? index : -1)).filter((index) => index >= 0);
  if (changed.length) {
    traces.push({ x: changed.map((i) => page.dates[i]), y: changed.map((i) => chart.value[i]), text: changed.map((i) => names[i]),
      mode: "markers", name: "changed", hoverinfo: "text+x", marker: { size: 18, symbol: "circle-open", color: "#c62828", line: { width: 2 } } });
  }
  const points = page.surveys.map((name, index) => (page.change_points.includes(name) ? index : -1)).filter((index) => index >= 0);
  if (points.length) {
    traces.push({ x: points.map((i) => page.dates[i]), y: points.map((i) => chart.value[i]), text: points.map((i) => names[i]),
      mode: "markers", name: "change point", hoverinfo: "text+x", marker: { size: 14, symbol: "x", color: "#1d1d1f" } });
  }
  const unit = chart.unit ? ` (${plotlyText(chart.unit)})` : "";
  const layout = { title: { text: plotlyText(chart.title) + unit }, margin: { t: 40 }, hovermode: "closest",
    xaxis: { title: { text: "survey date" } }, yaxis: { title: { text: plotlyText(chart.quantity) + unit } } };
  Plotly.react($(`trend-chart-${chart.quantity}`), traces, layout, { displaylogo: false, responsive: true });
}

// -- wiring ---------------------------------------------------------------------------------------
function wire() {
  const zone = $("drop-zone");
  zone.addEventListener("dragover", (event) => { event.preventDefault(); zone.classList.add("over"); });
  zone.addEventListener("dragleave", () => zone.classList.remove("over"));
  zone.addEventListener("drop", (event) => {
    event.preventDefault();
    zone.classList.remove("over");
    if (event.dataTransfer.files.length) sendFiles([...event.dataTransfer.files]);
  });
  $("file-input").addEventListener("change", (event) => { if (event.target.files.length) sendFiles([...event.target.files]); });
  $("example-button").addEventListener("click", useExample);
  $("sheet-select").addEventListener("change", chooseSheet);
  $("command-select").addEventListener("change", (event) => chooseCommand(event.target.value));
  $("circuit-table-select").addEventListener("change", showCircuitTable);
  $("run-button").addEventListener("click", run);
  $("cancel-button").addEventListener("click", cancel);
  $("experiment-select").addEventListener("change", (event) => { state.experiment = Number(event.target.value); showExperiment(); });
  window.addEventListener("pagehide", () => navigator.sendBeacon("/api/end"));
  startSession();
}

document.addEventListener("DOMContentLoaded", wire);
