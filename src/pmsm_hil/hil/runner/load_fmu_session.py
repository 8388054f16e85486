"""A load FMU instance for one run: unzipped into a temporary folder, its binary opened and instantiated by the
C loop's loop_fmu.c (dlopen, fmi2Instantiate / fmi3InstantiateCoSimulation), parameters set, initialised at
t = 0 with the start speed; the C loop then steps it each period. By default all of it happens in the FMU's own
process (`LoadFmuProcess`), so a crash, exit or hang of the FMU ends the run instead of killing or holding it.
Closed (terminated, freed, process ended, folder removed) after the run."""

from __future__ import annotations

import shutil
import tempfile
import threading
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pmsm_hil.hil.load_fmu.errors import LoadFmuCrashError, LoadFmuStepError
from pmsm_hil.hil.runner.load_fmu_process import LoadFmuProcess, describe_exit
from pmsm_hil.hil.runner.stop_request import deferred_interrupts

if TYPE_CHECKING:
    from pmsm_hil.hil.load_fmu.description import LoadFmuModel

#: |torque output| [N·m] beyond which the FMU's output is taken as absurd: the call fails, the run ends (far
#: above any machine this tool models: a bound on nonsense such as 1e30, not a rating check)
TORQUE_LIMIT_NM = 1.0e6
#: how often a call of the initialisation made in a worker thread lets Ctrl-C through [s]
_JOIN_S = 0.05

#: the FMI function behind each NL_FMU_CALL_* (FMI 2, FMI 3)
_CALLS = {
    1: ("dlopen", "dlopen"), 2: ("dlsym", "dlsym"),
    3: ("fmi2Instantiate", "fmi3InstantiateCoSimulation"), 4: ("fmi2SetupExperiment", "-"),
    5: ("fmi2EnterInitializationMode", "fmi3EnterInitializationMode"),
    6: ("fmi2ExitInitializationMode", "fmi3ExitInitializationMode"),
    7: ("fmi2Set*", "fmi3Set*"), 8: ("fmi2GetReal", "fmi3GetFloat64"), 9: ("fmi2DoStep", "fmi3DoStep"),
    10: ("fmi2GetReal", "fmi3GetFloat64"), 11: ("fmi2GetReal", "fmi3GetFloat64"),
}
#: loop_fmu.h NL_FMU_ENDED_*
_CRASHED, _HUNG, _STOPPED = 1, 2, 3
_STATUS = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")


class LoadFmuSession:
    """The instance the C loop steps (`fmu`: its nl_fmu_t *); `torque0` [N·m]: the output after initialisation
    at the start speed (the torque of the first period unless the FMU's output depends on the speed at once).
    `ts_s` [s] numbers the period of a failure; `timeout_s` [s]: the wall time one call may take in the FMU's
    process before it is hung (`--step-timeout`)."""

    def __init__(self, model: LoadFmuModel, ffi: Any, lib: Any, speed0_rad_s: float, *, ts_s: float = 1e-4,
                 timeout_s: float = 0.5) -> None:
        self.model = model
        self._ffi, self._lib = ffi, lib
        self._ts_s, self._timeout_s = ts_s, timeout_s
        self._dir = Path(tempfile.mkdtemp(prefix="hil-load-fmu-"))
        self.fmu = ffi.new("nl_fmu_t *")
        self.fmu.torque_limit = TORQUE_LIMIT_NM
        self.fmu.death_fd = -1
        self._open = False
        self._running = False
        self.process: LoadFmuProcess | None = None
        self._exit_status: int | None = None
        try:
            if model.spec.isolation == "process":
                self.process = LoadFmuProcess(lib, self.fmu, timeout_s)
            with zipfile.ZipFile(model.spec.path) as zf:
                zf.extractall(self._dir)
            resources = self._dir / "resources"
            resource = resources.as_uri() + "/" if model.fmi_version == 2 else f"{resources}/"
            rc = self._call(lib.nl_fmu_open, self.fmu, model.fmi_version,
                            str(self._dir / model.binary_member).encode(), b"load", model.token.encode(),
                            resource.encode(), model.vr_speed, model.vr_torque)
            self._open = True  # closed even after a failed open (contained: the process is ended)
            if rc != 0:
                raise self._init_failed()
            if self._call(lib.nl_fmu_enter_init, self.fmu, 0.0) != 0:
                raise self._init_failed()
            for p in model.params:
                if self._call(lib.nl_fmu_set, self.fmu, p.vr, p.kind, p.value) != 0:
                    raise self._init_failed(f" (--load-fmu-set {p.name}={p.value:g})")
            if self._call(lib.nl_fmu_exit_init, self.fmu, speed0_rad_s) != 0:
                raise self._init_failed()
        except BaseException:
            self.close()
            raise
        self.torque0 = float(self.fmu.torque)
        self._running = True

    def _init_failed(self, suffix: str = "") -> LoadFmuStepError:
        """The error of a failed set-up call: LoadFmuCrashError when the FMU's process crashed, exited or hung
        (a safety stop), else LoadFmuStepError (the FMU refused: an FMI status, a NULL instance, its binary)."""
        line = f"{self.failure()}{suffix}"
        if self.contained_failure:
            return LoadFmuCrashError(line, self.metrics())
        return LoadFmuStepError(line)

    def _call(self, fn: Callable[..., int], *args: Any) -> int:
        """An initialisation call; contained, made in a worker thread so that Ctrl-C/SIGTERM are seen at once
        whatever the FMU does: they stop the call's wait (`nl_fmu_stop`) and raise KeyboardInterrupt here (the
        run is not started yet: nothing to stop safely)."""
        if self.process is None:
            return int(fn(*args))
        result: list[int] = []
        worker = threading.Thread(target=lambda: result.append(int(fn(*args))), name="hil-load-fmu-init",
                                  daemon=True)
        with deferred_interrupts() as request, request.hook(self.stop):  # the run's, when it defers them
            worker.start()
            try:
                while worker.is_alive():
                    worker.join(_JOIN_S)
            except BaseException:
                self.stop()
                worker.join()
                raise
        if request.requested:
            raise KeyboardInterrupt
        return result[0] if result else -1

    @property
    def ended(self) -> int:
        """How the FMU's process ended a call (loop_fmu.h NL_FMU_ENDED_*: 0 none, 1 crashed, 2 hung, 3 stopped)."""
        return int(self.fmu.ended)

    @property
    def contained_failure(self) -> bool:
        """The FMU's process crashed, exited or hung (a safety stop, exit 3), rather than an FMI call failing."""
        return self.ended in (_CRASHED, _HUNG)

    def stop(self) -> None:
        """End any wait for the FMU's process at once (Ctrl-C, SIGTERM, the run's own stop); any thread."""
        if self.process is not None:
            self._lib.nl_fmu_stop(self.fmu)

    def _where(self) -> str:
        """`at period N`, or `while initialising` for a call before the run."""
        if not self._running:
            return "while initialising"
        return f"at period {round(float(self.fmu.t_fail) / self._ts_s)}"

    def _contained(self, name: str) -> str:
        """The line of a crashed or hung FMU process (killed when hung)."""
        where = f"load FMU '{self.model.model_name}' ({self.model.spec.path})"
        if self.ended == _HUNG:
            if self.process is not None:
                self.process.close(kill=True)
            return (f"{where} hung: {name} {self._where()} did not return within --step-timeout "
                    f"{self._timeout_s:g} s (wall time); its process killed")
        if self._exit_status is None and self.process is not None:
            self._exit_status = self.process.exit_status()
        how = describe_exit(self._exit_status) if self._exit_status is not None else "ended"
        return f"{where} crashed ({how} in {name} {self._where()})"

    def failure(self) -> str:
        """One line: which FMI call failed, where, with what status and the FMU's last logged message; or how
        its process crashed or hung, in which call, at which period."""
        f = self.fmu
        call = int(f.failed_call)
        name = _CALLS.get(call, ("?", "?"))[0 if self.model.fmi_version == 2 else 1]
        if self.contained_failure:
            return self._contained(name)
        message = self._ffi.string(f.message).decode("utf-8", "replace").strip()
        where = f"load FMU '{self.model.model_name}' ({self.model.spec.path})"
        if call == 11:  # our own bound, not the FMU's log
            return f"{where}: {name} at t = {float(f.t_fail):.6g} s: {message}"
        if call in (1, 2):
            what = "cannot open its binary" if call == 1 else "its binary lacks a function"
            return f"{where}: {what}: {message}"
        status = int(f.status)
        prefix = "fmi2" if self.model.fmi_version == 2 else "fmi3"
        said = f"returned {prefix}{_STATUS[status] if 0 <= status < len(_STATUS) else status}"
        if call == 3:
            said = "returned NULL"
        elif call == 10:
            said = "gave a non-finite torque"
        elif call == 11:
            said = "gave an out-of-range value"
        text = f"{where}: {name} at t = {float(f.t_fail):.6g} s {said}"
        return f"{text} (FMU log: {message})" if message else text

    def metrics(self) -> dict[str, Any]:
        """metrics.json `load_fmu`: the model's facts and the steps and warnings of the run."""
        return {**self.model.as_metrics(), "steps": int(self.fmu.steps), "warnings": int(self.fmu.warnings)}

    def close(self) -> None:
        """Terminate and free the instance, close the library, end the FMU's process (killed if it crashed,
        hung or was stopped), remove the unzipped folder (twice is fine)."""
        if self._open:
            self.fmu.stop = 0  # the run's own stop must not cut the orderly close short
            self._lib.nl_fmu_close(self.fmu)
            self._open = False
        if self.process is not None:
            self.process.close(kill=self.ended != 0)
        shutil.rmtree(self._dir, ignore_errors=True)
