// The live page: subscribes to /events (server-sent events) of one session and draws its state.
// The token and the session of the page's URL (?token=T&session=ID) are passed on to /events.
// window.wearnavState holds the latest state received (for people and for tests).
"use strict";

(() => {
  const params = new URLSearchParams(window.location.search);
  const query = new URLSearchParams();
  for (const key of ["token", "session"]) if (params.get(key)) query.set(key, params.get(key));
  const $ = id => document.getElementById(id);
  const canvas = $("map");
  window.wearnavState = null;
  window.wearnavEvents = 0;

  function text(el, value) { if (el.textContent !== String(value)) el.textContent = value; }

  function length(path) {
    let s = 0;
    for (let i = 1; i < path.length; i++) s += Math.hypot(path[i][1] - path[i - 1][1], path[i][2] - path[i - 1][2]);
    return s;
  }

  function render() {
    const st = window.wearnavState;
    if (!st) return;
    // dashed after the last final point (all of it while nothing is final yet)
    WearnavDraw.draw(canvas, st, {redraw: render, provisionalFrom: st.final_t_s === null ? -Infinity : st.final_t_s});
    text($("session"), `session ${st.session || "?"} · ${st.messages || 0} messages`);
    // "unknown": the model is unsure (issue 35); the page says so (and why, on hover) instead of a confident wrong word
    text($("activity"), st.activity ? st.activity.label : "–");
    $("activity").title = st.activity && st.activity.note ? st.activity.note : "";
    $("activity").dataset.label = st.activity ? st.activity.label : "";
    text($("points"), (st.path || []).length);
    text($("length"), Math.round(length(st.path || [])));
    text($("anchor"), st.anchor === "none" ? "not on a map (no fixes used)"
      : st.anchor === "start" ? "placed from --start (no plan; fixes not used)" : `placed on fixes (${st.anchor})`);
    text($("time"), (st.t_s || 0).toFixed(1));
    text($("nfixes"), (st.fixes || []).length);
    const now = Date.now() / 1000;
    const body = $("devices").tBodies[0];
    body.replaceChildren(...Object.entries(st.devices || {}).map(([name, d]) => {
      const tr = document.createElement("tr");
      tr.className = d.stopped ? "stopped" : "";
      tr.dataset.device = name;
      for (const cell of [name, `${Number(d.rate_hz).toFixed(1)} Hz`,
                          `${d.stopped ? "stopped, " : ""}${Math.max(0, now - d.last_seen_unix_s).toFixed(0)} s ago`]) {
        const td = document.createElement("td");
        td.textContent = cell;
        tr.appendChild(td);
      }
      return tr;
    }));
    const stopped = Object.entries(st.devices || {}).filter(([, d]) => d.stopped).map(([n]) => n);
    $("banner").className = stopped.length ? "show" : "";
    text($("banner"), stopped.length ? `${stopped.join(", ")} stopped sending` : "");
    $("warnings").innerHTML = "";
    for (const w of st.warnings || []) {
      const li = document.createElement("li");
      li.textContent = w;
      $("warnings").appendChild(li);
    }
  }

  function connect() {
    const source = new EventSource(`/events${query.toString() ? "?" + query : ""}`);
    source.onopen = () => text($("status"), "live");
    source.onmessage = ev => {
      window.wearnavState = JSON.parse(ev.data);
      window.wearnavEvents += 1;
      render();
    };
    source.onerror = () => {  // EventSource reconnects itself, except after a refusal (no session yet: 404)
      text($("status"), "disconnected: retrying");
      if (source.readyState === EventSource.CLOSED) setTimeout(connect, 2000);
    };
  }

  window.addEventListener("resize", render);
  setInterval(render, 1000);  // last-seen ages move on between events
  connect();
})();
