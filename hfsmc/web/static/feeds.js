// hfsmc view --web: the panels a component's feeds fill (monitor minor version 1 on):
// the vehicle panel, the user drivers' snapshots and the camera's frames. A ros2
// interface's topics and map are ros2.js's. Part of window.hfsmcView (page.js).
"use strict";

(function (hv) {
  const {$, el, seconds} = hv;

  // -- the vehicle panel and the camera's frames (monitor minor version 1) ---------------
  function showFeeds(feeds) {
    const vehicles = feeds.vehicle || [], cameras = feeds.camera || [];
    const drivers = $("hv-drivers");
    drivers.hidden = (feeds.driver || []).length === 0;
    for (const t of [...drivers.querySelectorAll("table")]) t.remove();
    const vbox = $("hv-vehicles"), cbox = $("hv-cameras");
    vbox.hidden = vehicles.length === 0;
    cbox.hidden = cameras.length === 0;
    for (const t of [...vbox.querySelectorAll("table")]) t.remove();
    for (const f of [...cbox.querySelectorAll("figure")]) f.remove();
    for (const name of vehicles) {
      const table = el("table", "hv-vehicle");
      table.dataset.name = name;
      if (vehicles.length > 1) table.appendChild(el("caption", "", name));
      const body = table.appendChild(el("tbody"));
      for (const [key, label] of [["mode", "mode"], ["armed", "armed"], ["altitude", "altitude"],
                                  ["position", "position"], ["velocity", "velocity"],
                                  ["battery", "battery"], ["link", "link"]]) {
        const tr = el("tr");
        tr.dataset.key = key;
        tr.append(el("th", "", label), el("td", "", "–"));
        body.appendChild(tr);
      }
      vbox.appendChild(table);
    }
    for (const name of cameras) {
      const fig = el("figure", "hv-camera");
      fig.dataset.name = name;
      const img = el("img");
      img.alt = "the latest frame of " + name;
      fig.append(img, el("figcaption", "", name + ": no frame yet (a snippet has not read one)"));
      cbox.appendChild(fig);
    }
  }

  function fixed(x, digits) { return typeof x === "number" ? x.toFixed(digits) : "–"; }
  function onVehicle(msg) {
    const table = [...document.querySelectorAll("#hv-vehicles table")].find((t) => t.dataset.name === msg.name);
    if (!table) return;
    const cell = (key) => table.querySelector('tr[data-key="' + key + '"] td');
    const three = (v, unit) => v ? "N " + fixed(v[0], 2) + "  E " + fixed(v[1], 2) + "  D " + fixed(v[2], 2) + " " + unit : "–";
    cell("mode").textContent = msg.mode || "–";
    cell("armed").textContent = msg.armed ? "ARMED" : "disarmed";
    cell("armed").className = msg.armed ? "hv-armed" : "";
    cell("altitude").textContent = typeof msg.altitude === "number" ? fixed(msg.altitude, 2) + " m" : "–";
    cell("altitude").dataset.value = typeof msg.altitude === "number" ? String(msg.altitude) : "";
    cell("position").textContent = three(msg.position, "m");
    cell("velocity").textContent = three(msg.velocity, "m/s");
    cell("battery").textContent = typeof msg.battery === "number" ? msg.battery + " %" : "–";
    const age = typeof msg.link_age === "number" ? fixed(msg.link_age, 1) + " s ago" : "never";
    cell("link").textContent = msg.connected ? "heartbeat " + age : "lost (heartbeat " + age + ")";
    cell("link").className = msg.connected ? "" : "hv-lost";
  }

  // A user driver's snapshot (monitor minor 4): one small table per interface, its
  // fields in the declaration's order; text only (textContent), whatever the driver says.
  function onDriver(msg) {
    if (!Array.isArray(msg.fields)) return;
    const box = $("hv-drivers");
    let table = [...box.querySelectorAll("table")].find((t) => t.dataset.name === msg.name);
    if (!table) {
      table = el("table", "hv-driver");
      table.dataset.name = msg.name;
      table.appendChild(el("caption", "", ""));
      table.appendChild(el("tbody"));
      box.appendChild(table);
      box.hidden = false;
    }
    table.querySelector("caption").textContent =
      msg.kind + " " + msg.name + (msg.live === false ? " (playback)" : "");
    const body = table.querySelector("tbody");
    const rows = new Map([...body.querySelectorAll("tr")].map((tr) => [tr.dataset.key, tr]));
    for (const f of msg.fields) {
      let tr = rows.get(f.name);
      if (!tr) {
        tr = el("tr");
        tr.dataset.key = f.name;
        tr.append(el("th", "", f.name), el("td", "", ""));
        body.appendChild(tr);
        rows.set(f.name, tr);
      }
      const v = f.value;
      tr.querySelector("td").textContent = v === null || v === undefined ? "–"
        : typeof v === "number" ? String(Number(v.toPrecision(6))) : String(v);
    }
  }

  function onFrame(msg) {
    const fig = [...document.querySelectorAll("#hv-cameras figure")].find((f) => f.dataset.name === msg.name);
    if (!fig || typeof msg.jpeg !== "string") return;
    fig.querySelector("img").src = "data:image/jpeg;base64," + msg.jpeg;
    fig.dataset.t = String(msg.t);
    fig.querySelector("figcaption").textContent =
      msg.name + ": t " + seconds(msg.t) + " s, " + msg.width + "×" + msg.height;
  }

  Object.assign(hv, {showFeeds, onVehicle, onDriver, onFrame});
})(window.hfsmcView);
