"""A load FMU instance for one run: unzipped into a temporary folder, its binary opened and instantiated by the
C loop's loop_fmu.c (dlopen, fmi2Instantiate / fmi3InstantiateCoSimulation), parameters set, initialised at
t = 0 with the start speed; the C loop then steps it each period. Closed (terminated, freed, folder removed)
after the run."""

from __future__ import annotations

import shutil
import tempfile
import zipfile
from pathlib import Path
from typing import Any

from pmsm_hil.hil.load_fmu.description import LoadFmuModel
from pmsm_hil.hil.load_fmu.errors import LoadFmuStepError

#: the FMI function behind each NL_FMU_CALL_* (FMI 2, FMI 3)
_CALLS = {
    1: ("dlopen", "dlopen"), 2: ("dlsym", "dlsym"),
    3: ("fmi2Instantiate", "fmi3InstantiateCoSimulation"), 4: ("fmi2SetupExperiment", "-"),
    5: ("fmi2EnterInitializationMode", "fmi3EnterInitializationMode"),
    6: ("fmi2ExitInitializationMode", "fmi3ExitInitializationMode"),
    7: ("fmi2Set*", "fmi3Set*"), 8: ("fmi2GetReal", "fmi3GetFloat64"), 9: ("fmi2DoStep", "fmi3DoStep"),
    10: ("fmi2GetReal", "fmi3GetFloat64"),
}
_STATUS = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")


class LoadFmuSession:
    """The instance the C loop steps (`fmu`: its nl_fmu_t *); `torque0` [N·m]: the output after initialisation
    at the start speed (the torque of the first period unless the FMU's output depends on the speed at once)."""

    def __init__(self, model: LoadFmuModel, ffi: Any, lib: Any, speed0_rad_s: float) -> None:
        self.model = model
        self._ffi, self._lib = ffi, lib
        self._dir = Path(tempfile.mkdtemp(prefix="hil-load-fmu-"))
        self.fmu = ffi.new("nl_fmu_t *")
        self._open = False
        try:
            with zipfile.ZipFile(model.spec.path) as zf:
                zf.extractall(self._dir)
            resources = self._dir / "resources"
            resource = resources.as_uri() + "/" if model.fmi_version == 2 else f"{resources}/"
            rc = lib.nl_fmu_open(self.fmu, model.fmi_version, str(self._dir / model.binary_member).encode(),
                                 b"load", model.token.encode(), resource.encode(), model.vr_speed, model.vr_torque)
            if rc != 0:
                raise LoadFmuStepError(self.failure())
            self._open = True
            if lib.nl_fmu_enter_init(self.fmu, 0.0) != 0:
                raise LoadFmuStepError(self.failure())
            for p in model.params:
                if lib.nl_fmu_set(self.fmu, p.vr, p.kind, p.value) != 0:
                    raise LoadFmuStepError(f"{self.failure()} (--load-fmu-set {p.name}={p.value:g})")
            if lib.nl_fmu_exit_init(self.fmu, speed0_rad_s) != 0:
                raise LoadFmuStepError(self.failure())
        except BaseException:
            self.close()
            raise
        self.torque0 = float(self.fmu.torque)

    def failure(self) -> str:
        """One line: which FMI call failed, where, with what status and the FMU's last logged message."""
        f = self.fmu
        call = int(f.failed_call)
        name = _CALLS.get(call, ("?", "?"))[0 if self.model.fmi_version == 2 else 1]
        message = self._ffi.string(f.message).decode("utf-8", "replace").strip()
        where = f"load FMU '{self.model.model_name}' ({self.model.spec.path})"
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
        text = f"{where}: {name} at t = {float(f.t_fail):.6g} s {said}"
        return f"{text} (FMU log: {message})" if message else text

    def metrics(self) -> dict[str, Any]:
        """metrics.json `load_fmu`: the model's facts and the steps and warnings of the run."""
        return {**self.model.as_metrics(), "steps": int(self.fmu.steps), "warnings": int(self.fmu.warnings)}

    def close(self) -> None:
        """Terminate and free the instance, close the library, remove the unzipped folder (twice is fine)."""
        if self._open:
            self._lib.nl_fmu_close(self.fmu)
            self._open = False
        shutil.rmtree(self._dir, ignore_errors=True)
