"""The monitor's page: one Bokeh document per viewer (a session), fed from the shared `Hub`.

Tab "Runs in progress": the followed run (a menu when several go), its published state, the pause, resume
and abort buttons (enabled for the controller only; `rdea_lab.monitor.access`), and its channels streamed
into a ColumnDataSource every `TICK` (``source.stream(..., rollover=KEEP)``), the twin's predicted force
beside the measured one when the monitor has a parameter set, and the paused spans shaded where the run
records ``paused``. Tab "Finished runs": the catalogue in a DataTable; a row selected shows that run.
"""

from __future__ import annotations

import functools
from html import escape as esc  # every text from a journal, a run or an error: the page shows it, never runs it
import time as _time

import numpy as np
from bokeh.layouts import column, row
from bokeh.models import (Button, ColumnDataSource, DataTable, Div, NumberFormatter, Range1d, Select, TabPanel,
                          Tabs, TableColumn, TextInput)
from bokeh.plotting import figure

from .access import NotController, _argument
from .feed import CHANNELS, KEEP
from .hub import CATALOG_COLUMNS, TICK

#: Points sent to one viewer per tick at most (a catch-up is thinned; a live tick is far below it).
PER_TICK = 4000
#: (label, unit, scale) of each channel's axis.
AXES = {"force": ("force", "N", 1.0), "stretch": ("stretch", "1", 1.0), "voltage": ("voltage", "kV", 1e-3),
        "capacitance": ("capacitance", "nF", 1e9), "current": ("current", "uA", 1e6), "paused": ("pause", "", 1.0)}
#: The values of a run's ``paused`` flag (the phase of each sample) and their labels.
PHASES = {0: "running", 1: "ramping down", 2: "held", 3: "ramping up"}
#: Colours: measured, predicted, paused shade.
COLOURS = {"measured": "#1f5fa8", "predicted": "#e07b00", "paused": "#c8c8c8"}

#: The columns of a finished run's source.
FINISHED_KEYS = ("time", *CHANNELS, "paused_on")

HELP = ("<b>Closing this page changes nothing for the run.</b> The run's heartbeat is the rig's (the run "
        "process's driver talking to the rig), not this page's: a lost or closed browser neither pauses nor "
        "stops anything. Pause, Resume and Abort write a request into the run's journal folder, which the run "
        "reads between blocks of samples; only the page opened with the monitor's <i>control URL</i> may press "
        "them (the server checks it again, whatever the page shows).")



def refused_document(doc) -> None:
    """What a session without the viewing token gets: one line, no data, no callbacks."""
    doc.title = "rdea-lab monitor: refused"
    doc.add_root(Div(text="refused: this monitor needs <code>?token=</code> with the token of its "
                     "<code>--token-file</code>"))


def _empty(keys) -> dict:
    return {k: np.empty(0) for k in keys}


class LiveView:
    """One viewer's page (a Bokeh document) and its callbacks.

    Parameters
    ----------
    doc : bokeh.document.Document
    hub : Hub
    controls : Controls
    arguments : dict
        The session's request arguments (``control``: the secret, if the page was opened with it).
    role : {"controller", "viewer"}
    """

    KEYS = ("time", *CHANNELS, "force_pred", "paused_on")

    def __init__(self, doc, hub, controls, arguments: dict, role: str):
        self.doc, self.hub, self.controls, self.role = doc, hub, controls, role
        self.given = _argument(arguments, "control")  # re-checked by Controls.press at every press
        self.key: str | None = None
        self.seq = 0
        self.runs_version = self.catalog_version = -1
        self.ticks = 0
        self.present: set[str] | None = None
        self.source = ColumnDataSource(_empty(self.KEYS), name="live")
        self.finished = ColumnDataSource(_empty(FINISHED_KEYS), name="finished")
        self.catalog = ColumnDataSource({c: [] for c in CATALOG_COLUMNS}, name="catalog")
        doc.title = "rdea-lab monitor"
        doc.add_root(self._layout())
        doc.add_periodic_callback(self.tick, int(TICK * 1000))
        self.tick()

    # -------------------------------------------------------------- layout
    def _figures(self, source, names, height=170, prediction=True):
        """A figure per channel of ``names`` on one time axis; with ``paused`` among them, the paused spans
        shaded across every figure and the pause's phase drawn below them."""
        figs, shared = {}, None
        shade = "paused" in names
        for name in names:
            label, unit, _ = AXES[name]
            f = figure(height=height if name != "paused" else 110, sizing_mode="stretch_width",
                       tools="xpan,xwheel_zoom,box_zoom,reset,save", toolbar_location="right",
                       y_axis_label=f"{label} [{unit}]" if unit else label,
                       **({"x_range": shared} if shared is not None else {}))
            shared = f.x_range
            if name == "paused":
                f.step(x="time", y="paused", source=source, mode="after", color="#777", line_width=1.2)
                f.y_range = Range1d(-0.3, 3.3)
                f.yaxis.ticker = list(PHASES)
                f.yaxis.major_label_overrides = dict(PHASES)
                f.yaxis.axis_label = "pause"
                figs[name] = f
                continue
            if name == "force" and prediction:
                lines = [f.line(x="time", y="force", source=source, color=COLOURS["measured"], line_width=1.2,
                                legend_label="measured"),
                         f.line(x="time", y="force_pred", source=source, color=COLOURS["predicted"], line_width=1.2,
                                line_dash="dashed", legend_label="twin")]
                f.legend.location = "top_left"
                f.legend.background_fill_alpha = 0.6
            else:
                lines = [f.line(x="time", y=name, source=source, color=COLOURS["measured"], line_width=1.2)]
            if shade:  # the whole height, on a range of its own (the channel's range follows its lines only)
                f.y_range.renderers = lines
                f.extra_y_ranges = {"pause": Range1d(0, 1)}
                f.varea(x="time", y1=0.0, y2="paused_on", source=source, y_range_name="pause",
                        color=COLOURS["paused"], alpha=0.5, level="underlay")
            f.xaxis.visible = False
            figs[name] = f
        last = list(figs.values())[-1]
        last.xaxis.visible = True
        last.xaxis.axis_label = "time [s]"
        return figs

    def _layout(self):
        title = Div(text=f"<h2 style='margin:4px 0'>rdea-lab monitor <span style='font-weight:normal;"
                    f"font-size:60%'>{esc(str(self.hub.folder))}</span></h2>", sizing_mode="stretch_width")
        badge = ("<span style='background:#2e7d32;color:white;padding:2px 8px;border-radius:3px'>controller"
                 "</span>" if self.role == "controller" else
                 "<span style='background:#777;color:white;padding:2px 8px;border-radius:3px'>viewer</span> "
                 "(open the control URL the monitor printed to operate runs)")
        self.role_div = Div(text=badge)
        self.help = Div(text=f"<p style='font-size:85%;color:#444;max-width:900px'>{HELP}</p>",
                        sizing_mode="stretch_width")
        self.select = Select(title="Run in progress", options=[], value="", width=420, name="run")
        self.select.on_change("value", self._chosen)
        self.state = Div(text="no run in progress below this folder yet", name="state", width=560)
        self.reason = TextInput(title="Reason (recorded with the request)", width=300, name="reason")
        controller = self.role == "controller"
        self.buttons = {a: Button(label=a.capitalize(), button_type=kind, disabled=not controller, width=90,
                                  name=a, css_classes=[f"rdea-{a}"])
                        for a, kind in (("pause", "warning"), ("resume", "success"), ("abort", "danger"))}
        for action, b in self.buttons.items():
            b.on_click(functools.partial(self.press, action))
        self.message = Div(text="", name="message", width=500)
        waiting = Div(text="<i>the run's channels appear with its first samples</i>")
        self.plots = column(waiting, sizing_mode="stretch_width")  # the run's channels, made at its first points
        live = column(row(self.select, self.state),
                      row(self.reason, *self.buttons.values(), self.message),
                      self.plots, sizing_mode="stretch_width")
        table = DataTable(source=self.catalog, height=260, sizing_mode="stretch_width", index_position=None,
                          columns=[TableColumn(field=c, title=c, formatter=NumberFormatter(format="0.[00]"))
                                   if c in ("duration_s", "samples") else TableColumn(field=c, title=c)
                                   for c in CATALOG_COLUMNS], name="catalog_table")
        self.catalog.selected.on_change("indices", self._picked)
        self.finished_title = Div(text="select a run in the table to see it", sizing_mode="stretch_width")
        self.finished_plots = column(Div(text=""), sizing_mode="stretch_width")
        done = column(table, self.finished_title, self.finished_plots, sizing_mode="stretch_width")
        tabs = Tabs(tabs=[TabPanel(child=live, title="Runs in progress"), TabPanel(child=done, title="Finished runs")],
                    sizing_mode="stretch_width")
        return column(title, row(self.role_div), self.help, tabs, sizing_mode="stretch_width")

    # -------------------------------------------------------------- callbacks
    def tick(self) -> None:
        """Every `TICK`: what is new in the hub, onto this page."""
        self.ticks += 1
        self.hub.update()
        if self.hub.runs_version != self.runs_version:
            self.runs_version = self.hub.runs_version
            runs = self.hub.runs()
            self.select.options = [(k, label) for k, label in runs]
            if runs and (self.key is None or self.key not in self.hub.feeds):
                live = [k for k, _ in runs if not self.hub.feeds[k].finished]
                self.select.value = (live or [runs[0][0]])[0]  # calls _chosen
        feed = self.hub.feeds.get(self.key) if self.key else None
        if feed is not None:
            seq, points, reset = feed.since(self.seq, limit=PER_TICK)
            if points is not None:
                data = shown(points, self.KEYS)
                if reset:
                    self.source.data = data
                else:
                    self.source.stream(data, rollover=KEEP)
            self.seq = seq
            if feed.measured and feed.measured != self.present:
                self.present = set(feed.measured)
                # only the channels this run measures get a figure: every glyph on the source is updated at
                # every stream, so one per channel that shows nothing would cost the browser for nothing
                self.plots.children = list(self._figures(self.source, [c for c in CHANNELS if c in self.present],
                                                         prediction=self.hub.params is not None).values())
        if self.ticks % 5 == 1:
            self._show_state(feed)
        if self.hub.catalog_version != self.catalog_version:
            self.catalog_version = self.hub.catalog_version
            if self.hub.catalog_rows is not None:
                self.catalog.data = {c: self.hub.catalog_rows.get(c, []) for c in CATALOG_COLUMNS}
            if self.hub.catalog_error:
                self.finished_title.text = f"<span style='color:#a00'>{esc(self.hub.catalog_error)}</span>"

    def _chosen(self, attr, old, new) -> None:
        self.key = new or None
        self.seq = 0
        self.source.data = _empty(self.KEYS)
        self.present = None  # the figures are made at the first points
        self.plots.children = [Div(text="<i>the run's channels appear with its first samples</i>")]
        self._show_state(self.hub.feeds.get(self.key) if self.key else None)

    def _show_state(self, feed) -> None:
        if feed is None:
            self.state.text = "no run in progress below this folder yet"
            return
        if feed.finished:
            self.state.text = (f"<b>finished</b>: {feed.samples} samples followed; its dataset "
                               f"<code>{esc(feed.dataset.name)}</code> is in the <i>Finished runs</i> tab")
            for b in self.buttons.values():
                b.disabled = True
            return
        s = self.hub.states.get(self.key) or {}
        state = s.get("state", "running (no state published)")
        try:
            age = f", {(_time.time() - float(s['updated'])):.0f} s ago" if "updated" in s else ""
        except (TypeError, ValueError):
            age = ""
        a = (feed.header or {}).get("attrs", {})
        text = (f"<b>{esc(str(state))}</b>{': ' + esc(str(s['reason'])) if s.get('reason') else ''}{age} &middot; "
                f"{esc(str(a.get('protocol_name', '?')))} on {esc(str(a.get('specimen_id', '?')))} "
                f"({esc(str(a.get('backend', '?')))}, {esc(str(a.get('sample_rate', '?')))} Hz) &middot; "
                f"{feed.samples} samples")
        if feed.tail.skipped:
            text += f" ({feed.tail.skipped} older ones not shown)"
        if feed.prediction is not None and feed.prediction.model:
            text += f" &middot; twin {feed.prediction.model.upper()}"
        if feed.prediction_error:
            text += f"<br><span style='color:#a00'>{esc(feed.prediction_error)}</span>"
        self.state.text = text
        for b in self.buttons.values():
            b.disabled = self.role != "controller"

    def press(self, action: str) -> None:
        """A control button: checked on the server (`Controls.press`), sent off the event loop."""
        if not self.key or self.key not in self.hub.feeds or self.hub.feeds[self.key].finished:
            self.message.text = "no run in progress to act on"
            return
        try:
            future = self.controls.press(self.given, self.hub.feeds[self.key].journal, action, self.reason.value)
        except NotController as exc:
            self.message.text = f"<span style='color:#a00'>refused: {esc(str(exc))}</span>"
            return
        self.message.text = f"{action}: sent, waiting for the run to answer ..."
        future.add_done_callback(lambda f: self.doc.add_next_tick_callback(functools.partial(self._answered,
                                                                                             action, f)))

    def _answered(self, action, future) -> None:
        try:
            state = future.result()
        except Exception as exc:  # noqa: BLE001 - the run's refusal or silence, said on the page
            self.message.text = f"<span style='color:#a00'>{action}: {esc(str(exc))}</span>"
            return
        if state.get("refused"):
            why = esc(str(state["refused"]))
            self.message.text = f"<span style='color:#a00'>{action} refused by the run: {why}</span>"
        else:
            self.message.text = f"{action}: the run is {esc(str(state.get('state', '?')))}"
        if self.key in self.hub.feeds and state.get("state"):  # its answer is its state now: shown at once
            self.hub.states[self.key] = state
            self._show_state(self.hub.feeds[self.key])

    def _picked(self, attr, old, new) -> None:
        if not new:
            return
        path = self.catalog.data["file"][new[0]]
        self.finished_title.text = f"reading {esc(path)} ..."

        def loaded(future):
            try:
                data = future.result()
            except Exception as exc:  # noqa: BLE001
                self.finished_title.text = (f"<span style='color:#a00'>{esc(path)}: {type(exc).__name__}: "
                                            f"{esc(str(exc))}</span>")
                return
            self.finished_title.text = f"<b>{esc(data.pop('title'))}</b>"
            self.finished.data = shown(data, FINISHED_KEYS)
            names = [c for c in CHANNELS if c in data and np.isfinite(data[c]).any()]
            self.finished_plots.children = list(self._figures(self.finished, names or ["force"], height=150,
                                                              prediction=False).values())

        future = self.hub.pool.submit(self.hub.finished_run, path)
        future.add_done_callback(lambda f: self.doc.add_next_tick_callback(functools.partial(loaded, f)))


def shown(points: dict, keys) -> dict:
    """Points in display units (`AXES`: kV, nF, uA), every key present (NaN where a run has no such channel)."""
    n = points["time"].size
    out = {}
    for k in keys:
        if k == "paused_on":  # 1 where the run is paused (any phase but running): the shade's height
            v = points.get("paused")
            out[k] = np.zeros(n) if v is None else np.where(np.nan_to_num(v) > 0, 1.0, 0.0)
            continue
        scale = AXES.get("force" if k == "force_pred" else k, ("", "", 1.0))[2]
        v = points.get(k)
        out[k] = np.full(n, np.nan) if v is None else (v * scale if scale != 1.0 else v)
    return out


def make_document(doc, hub, access, controls, on_session=None) -> LiveView | None:
    """Fill a new session's document: refused (no viewing token), or a `LiveView` for a controller or viewer."""
    context = doc.session_context
    arguments = context.request.arguments if context is not None and context.request is not None else {}
    role = access.role(arguments)
    if role == "refused":
        refused_document(doc)
        return None
    view = LiveView(doc, hub, controls, arguments, role)
    if on_session is not None:
        on_session(view)
    return view


__all__ = ["HELP", "LiveView", "make_document", "refused_document"]
