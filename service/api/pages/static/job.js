// Poll the job's status while it runs; reload the page once it has finished. (A live sweep's
// page follows its event stream instead: live.js.)
(function () {
  "use strict";
  var script = document.getElementById("job-script");
  var url = script.getAttribute("data-status-url");
  var bar = document.getElementById("job-progress");
  var frac = document.getElementById("job-fraction");
  var msg = document.getElementById("job-message");
  var status = document.getElementById("job-status");
  function tick() {
    fetch(url, { credentials: "same-origin", cache: "no-store" })
      .then(function (r) { return r.ok ? r.json() : null; })
      .then(function (d) {
        if (!d) { return; }
        bar.value = d.progress.fraction;
        frac.textContent = Math.round(100 * d.progress.fraction) + " %";
        frac.setAttribute("data-value", String(d.progress.fraction));
        msg.textContent = d.progress.message;
        status.textContent = d.status;
        if (d.done) { window.location.reload(); return; }
        window.setTimeout(tick, 1000);
      })
      .catch(function () { window.setTimeout(tick, 3000); });
  }
  window.setTimeout(tick, 1000);
})();
