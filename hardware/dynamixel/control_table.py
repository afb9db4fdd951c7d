"""X-series (Protocol 2.0) control table: addresses, sizes, units and the models palpate knows.

Values are from the ROBOTIS e-Manual for the XM430/XM540/XH430 family. Units convert raw register values
to SI: positions in ticks (4096 per revolution), velocity in 0.229 rpm, current in model-specific mA.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# address, size in bytes
MODEL_NUMBER = (0, 2)
FIRMWARE_VERSION = (6, 1)
ID = (7, 1)
BAUD_RATE = (8, 1)
RETURN_DELAY_TIME = (9, 1)
DRIVE_MODE = (10, 1)
OPERATING_MODE = (11, 1)
CURRENT_LIMIT = (38, 2)
VELOCITY_LIMIT = (44, 4)
MAX_POSITION_LIMIT = (48, 4)
MIN_POSITION_LIMIT = (52, 4)
TORQUE_ENABLE = (64, 1)
LED = (65, 1)
STATUS_RETURN_LEVEL = (68, 1)
HARDWARE_ERROR_STATUS = (70, 1)
GOAL_CURRENT = (102, 2)
GOAL_VELOCITY = (104, 4)
PROFILE_VELOCITY = (112, 4)
GOAL_POSITION = (116, 4)
MOVING = (122, 1)
PRESENT_CURRENT = (126, 2)
PRESENT_VELOCITY = (128, 4)
PRESENT_POSITION = (132, 4)
PRESENT_INPUT_VOLTAGE = (144, 2)
PRESENT_TEMPERATURE = (146, 1)

TABLE_SIZE = 147
EEPROM_END = 64  # addresses below this are EEPROM: writable only with torque off

MODE_CURRENT = 0
MODE_VELOCITY = 1
MODE_POSITION = 3
MODE_EXTENDED_POSITION = 4
MODE_CURRENT_POSITION = 5

# Baud-rate register value -> bits per second.
BAUD_CODES = {0: 9600, 1: 57600, 2: 115200, 3: 1_000_000, 4: 2_000_000, 5: 3_000_000, 6: 4_000_000, 7: 4_500_000}

VELOCITY_UNIT = 0.229 * 2.0 * math.pi / 60.0  # rad/s per register unit (0.229 rpm)
TICKS_PER_REV = 4096
CENTER_TICK = 2048


@dataclass(frozen=True)
class ServoModel:
    """What palpate needs to know about one servo model.

    Attributes:
        number: model number reported by ping (control table address 0).
        name: ROBOTIS model name.
        current_unit: A per present/goal current register unit.
        current_limit_max: largest current limit register value the model accepts.
        torque_constant: N*m per A, from the stall torque and stall current at 12 V.
        no_load_speed: rad/s at 12 V.
    """

    number: int
    name: str
    current_unit: float
    current_limit_max: int
    torque_constant: float
    no_load_speed: float


MODELS: dict[int, ServoModel] = {
    m.number: m
    for m in (
        ServoModel(1020, "XM430-W350", 2.69e-3, 1193, 4.1 / 2.3, 46 * 2 * math.pi / 60),
        ServoModel(1030, "XM430-W210", 2.69e-3, 1193, 3.0 / 2.3, 77 * 2 * math.pi / 60),
        ServoModel(1000, "XH430-W350", 2.69e-3, 689, 3.4 / 1.3, 46 * 2 * math.pi / 60),
        ServoModel(1120, "XM540-W270", 2.69e-3, 2047, 10.6 / 4.4, 30 * 2 * math.pi / 60),
    )
}


def model_by_name(name: str) -> ServoModel:
    """The model called ``name`` (case-insensitive); KeyError listing the known ones otherwise."""
    for m in MODELS.values():
        if m.name.lower() == name.lower():
            return m
    raise KeyError(f"unknown servo model {name!r}; known: {', '.join(m.name for m in MODELS.values())}")


def model_name(number: int) -> str:
    """Name of a model number, or ``"unknown (N)"``."""
    m = MODELS.get(number)
    return m.name if m else f"unknown ({number})"
