"""What more than one test module of the run engine uses."""

from rdea_lab.backends import TwinBackend


class RecordingTwin(TwinBackend):
    """The twin, recording the engine's calls that move or stop it (a setpoint reaches it only through
    `start`): ``calls`` lists ``"start"``, ``"abort"`` and ``"close"`` in the order they came."""

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.calls = []

    def start(self, plan):
        self.calls.append("start")
        super().start(plan)

    def abort(self, reason):
        self.calls.append("abort")
        super().abort(reason)

    def close(self):
        self.calls.append("close")
        super().close()
