"""The mechanical load as an FMU (FMI 2.0 / 3.0 Co-Simulation, `hil run --load-fmu`): the options
(`spec`), the model description read and checked with fmpy (`description`), and the instance the C loop steps
each period through the FMU's own C API (`session`). docs/plant.md "Load as an FMU"."""
