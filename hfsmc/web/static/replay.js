// hfsmc view --web: a replay's controls (`hfsmc view --web --replay`): play or pause,
// previous and next transition, speed and the timeline. What they show is the bridge's
// (shared by every page); what they do is sent to it as a command (docs/web.md). Part
// of window.hfsmcView (page.js).
"use strict";

(function (hv) {
  const {$, view, el, seconds} = hv;

  // A replay's position, playing or not, and speed: the bridge's, shared by every page.
  function onReplay(r) {
    view.playing = !!r.playing;
    $("hv-play").textContent = r.playing ? "pause" : "play";
    const line = $("hv-timeline");
    line.max = String(r.end);
    if (document.activeElement !== line || r.playing) line.value = String(r.t);
    $("hv-position").textContent = seconds(r.t) + " / " + seconds(r.end) + " s";
    document.body.dataset.position = String(r.t);
    const speed = $("hv-speed");
    if (document.activeElement !== speed && Number(speed.value) !== r.speed) {
      if (![...speed.options].some((o) => Number(o.value) === r.speed)) {
        speed.appendChild(el("option", "", r.speed + "×")).value = String(r.speed);
      }
      speed.value = String(r.speed);
    }
  }

  // The controls (the page's start, in app.js, calls this once).
  function startReplay() {
    const send = hv.send;
    $("hv-play").addEventListener("click", () => send({do: view.playing ? "pause" : "play"}));
    $("hv-next").addEventListener("click", () => send({do: "next"}));
    $("hv-previous").addEventListener("click", () => send({do: "previous"}));
    $("hv-speed").addEventListener("change", () => send({do: "speed", speed: Number($("hv-speed").value)}));
    $("hv-timeline").addEventListener("input", () => send({do: "seek", t: Number($("hv-timeline").value)}));
  }

  Object.assign(hv, {onReplay, startReplay});
})(window.hfsmcView);
