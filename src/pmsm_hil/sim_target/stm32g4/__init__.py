"""A virtual STM32G4 (Cortex-M4F core and RM0440 peripherals) that runs a firmware ELF unmodified against the plant."""
