"""The peripheral models of the virtual STM32G4, one per file, behind one registry (`base.REGISTRY`)."""
