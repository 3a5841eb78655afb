// hfsmc view --web: the header's account of the component: connected or not (and why,
// in the banner), the simulator's rate (--clock sim) and the overruns. Part of
// window.hfsmcView (page.js).
"use strict";

(function (hv) {
  const {$, view} = hv;

  function showStatus(status, note) {
    view.status = status;
    document.body.dataset.status = status;
    $("hv-status").textContent = status;
    const banner = $("hv-banner");
    banner.hidden = status === "connected" || status === "replay";
    banner.textContent = note || "";
  }

  // --clock sim: the time shown is the simulator's, and how fast it runs (null: the real
  // or virtual clock, nothing shown).
  function showRate(rate) {
    view.rate = typeof rate === "number" && isFinite(rate) ? rate : null;
    const r = $("hv-rate");
    r.hidden = view.rate === null;
    r.textContent = view.rate === null ? "" : "simulated, " + view.rate.toFixed(1) + "× real time";
    if (view.rate === null) delete document.body.dataset.simRate;
    else document.body.dataset.simRate = String(view.rate);
  }

  function showOverruns(n) {
    const o = $("hv-overruns");
    if (o.textContent === "overruns " + n) return;
    o.textContent = "overruns " + n;
    o.classList.toggle("hv-some", n > 0);
  }

  Object.assign(hv, {showStatus, showRate, showOverruns});
})(window.hfsmcView);
