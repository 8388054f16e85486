"""A fake board for peripheral-model tests: SRAM as a bytearray, the models by name, the NVIC as the list of pend
and clear calls, and `access` (the bus-master path) reaching memory or a model's registers as the CPU would."""

from __future__ import annotations

from typing import TypeVar

from pmsm_hil.sim_target.stm32g4.peripherals.base import REGISTRY, BoardError, Peripheral

SRAM = 0x2000_0000
SRAM_SIZE = 0x2_0000
P = TypeVar("P", bound=Peripheral)


class FakeBus:
    """A board holding `ram_size` bytes of RAM at `ram_base` (default: SRAM) and the models added with `add`."""

    def __init__(self, sysclk_hz: int = 170_000_000, *, ram_base: int = SRAM, ram_size: int = SRAM_SIZE) -> None:
        self.sram = bytearray(ram_size)
        self.ram_base = ram_base
        self.models: dict[str, Peripheral] = {}
        self.pended: list[int] = []
        self.cleared: list[int] = []
        self.clock = sysclk_hz

    def add(self, name: str) -> Peripheral:
        """Build the registered model `name` on this board."""
        self.models[name] = REGISTRY[name](self)
        return self.models[name]

    def add_model(self, name: str, kind: type[P]) -> P:
        """Build the registered model `name`, a `kind`, on this board."""
        model = self.add(name)
        assert isinstance(model, kind), type(model)
        return model

    def set_pending(self, irq: int) -> None:
        self.pended.append(irq)

    def clear_pending(self, irq: int) -> None:
        self.cleared.append(irq)

    def read_memory(self, address: int, size: int) -> bytes:
        start = address - self.ram_base
        assert start >= 0 and start + size <= len(self.sram), hex(address)
        return bytes(self.sram[start:start + size])

    def write_memory(self, address: int, data: bytes) -> None:
        start = address - self.ram_base
        assert start >= 0 and start + len(data) <= len(self.sram), hex(address)
        self.sram[start:start + len(data)] = data

    def peripheral(self, name: str) -> Peripheral:
        try:
            return self.models[name]
        except KeyError:  # as the board says it
            raise BoardError(f"the board has no {name} model") from None

    @property
    def sysclk_hz(self) -> int:
        return self.clock

    def access(self, address: int, size: int, value: int | None = None, *, now: int) -> int:
        for model in self.models.values():
            if model.base <= address < model.base + model.size:
                if value is None:
                    return model.read(address - model.base, size, now)
                model.write(address - model.base, size, value, now)
                return value
        if not self.ram_base <= address < self.ram_base + len(self.sram):
            raise BoardError(f"access at {address:#010x}, which the fake board does not model")
        if value is None:
            return int.from_bytes(self.read_memory(address, size), "little")
        self.write_memory(address, value.to_bytes(size, "little"))
        return value

    def word(self, address: int, size: int = 4) -> int:
        return int.from_bytes(self.read_memory(address, size), "little")

    def put(self, address: int, value: int, size: int = 4) -> None:
        self.write_memory(address, value.to_bytes(size, "little"))
