// An open live sweep's page follows the sweep's server-sent events: each "update" (a record was
// added) re-renders the page's content in place, "closed" loads the finished sweep's page.
// Without EventSource, or when the stream cannot be opened, it falls back to polling the job's
// status and reloading when a record arrived.
(function () {
  "use strict";
  var script = document.getElementById("live-script");
  var eventsUrl = script.getAttribute("data-events-url");
  var statusUrl = script.getAttribute("data-status-url");
  var seen = script.getAttribute("data-seen");  // the job message the page was rendered with
  var busy = false;
  var again = false;

  function render() {  // the page as the server renders it now, swapped in without a reload
    if (busy) { again = true; return; }
    busy = true;
    fetch(window.location.href, { credentials: "same-origin", cache: "no-store" })
      .then(function (r) { return r.ok ? r.text() : null; })
      .then(function (html) {
        if (html === null) { return; }
        var fresh = new DOMParser().parseFromString(html, "text/html").querySelector("main");
        var main = document.querySelector("main");
        if (fresh && main) { main.replaceWith(fresh); }
      })
      .catch(function () { again = true; })
      .then(function () {
        busy = false;
        if (again) { again = false; window.setTimeout(render, 200); }
      });
  }

  function poll() {  // the fallback: the job's status once a second
    fetch(statusUrl, { credentials: "same-origin", cache: "no-store" })
      .then(function (r) { return r.ok ? r.json() : null; })
      .then(function (d) {
        if (d && (d.done || d.progress.message !== seen)) {
          window.location.reload();
          return;
        }
        window.setTimeout(poll, 1000);
      })
      .catch(function () { window.setTimeout(poll, 3000); });
  }

  if (!window.EventSource) { window.setTimeout(poll, 1000); return; }
  var stream = new EventSource(eventsUrl);
  script.setAttribute("data-following", "events");
  stream.addEventListener("update", function () { render(); });
  stream.addEventListener("closed", function () {
    stream.close();
    window.location.reload();
  });
  stream.onerror = function () {
    // CONNECTING: the browser reconnects by itself (Last-Event-ID); CLOSED: the stream was
    // refused (an answer that is not an event stream), so poll instead
    if (stream.readyState === EventSource.CLOSED) {
      script.setAttribute("data-following", "polling");
      window.setTimeout(poll, 1000);
    }
  };
})();
