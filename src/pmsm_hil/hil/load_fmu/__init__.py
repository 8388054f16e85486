"""The mechanical load as an FMU (FMI 2.0 / 3.0 Co-Simulation, `hil run --load-fmu`): the options
(`spec`), the model description read and checked with fmpy (`description`), the FMI headers of the installed
fmpy the C loop builds against (`headers`), and the instance the C loop steps each period through the FMU's own
C API (`session`), by default in a process of its own (`process` from the run's side, `serve` the FMU's) so that
its crash or hang ends the run instead of killing or holding it. docs/plant.md "Load as an FMU"."""
