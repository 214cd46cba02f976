"""Pipe-wall materials and conveyed fluids by name: handbook values for a request's
``pipe.material`` and ``pipe.fluid`` (issue 34, item 7).

Every value is a typical room-temperature handbook figure, SI units, with its source and
temperature beside it.  Real materials vary (alloy, grade, temper; a polymer's modulus
with temperature and loading rate by tens of percent): for a design, give the measured or
specified values explicitly (``pipe.E``, ``pipe.density``, ``pipe.fluid_density``
override the named ones).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Material:
    """A pipe-wall material: Young's modulus ``E`` [Pa] and density [kg/m^3]."""

    E: float
    density: float
    source: str


@dataclass(frozen=True)
class Fluid:
    """A conveyed fluid: density [kg/m^3]."""

    density: float
    source: str


#: pipe-wall materials at about 20 C
MATERIALS: dict[str, Material] = {
    # carbon steel: E 200-210 GPa, rho 7850 kg/m^3 (Engineering ToolBox, "Young's Modulus,
    # Tensile Strength and Yield Strength Values for some Materials" and "Metals and
    # Alloys - Densities"; ASM Handbook vol. 1); 20 C
    "steel": Material(E=200e9, density=7850.0, source="Engineering ToolBox; ASM Handbook vol. 1"),
    # austenitic stainless steel (304/316): E 193 GPa, rho 8000 kg/m^3 (ASM Handbook vol. 1,
    # "Properties of Wrought Stainless Steels"); 20 C
    "stainless": Material(E=193e9, density=8000.0, source="ASM Handbook vol. 1"),
    # aluminium alloy 6061-T6: E 68.9 GPa, rho 2700 kg/m^3 (ASM Handbook vol. 2,
    # "Properties of Wrought Aluminum and Aluminum Alloys"); 20 C
    "aluminium": Material(E=69e9, density=2700.0, source="ASM Handbook vol. 2"),
    # copper (C12200, plumbing tube): E 117 GPa, rho 8960 kg/m^3 (CRC Handbook of Chemistry
    # and Physics, density of the elements; ASM Handbook vol. 2); 20 C
    "copper": Material(E=117e9, density=8960.0, source="CRC Handbook; ASM Handbook vol. 2"),
    # rigid PVC (PVC-U): E about 3 GPa, rho 1400 kg/m^3 (Engineering ToolBox, "Polyvinyl
    # Chloride (PVC) - Properties"; PVC pipe makers give 2.8-3.3 GPa); 20 C
    "PVC": Material(E=3.0e9, density=1400.0, source="Engineering ToolBox, PVC properties"),
    # high-density polyethylene (PE 100): short-term E 0.8-1.1 GPa, rho 950 kg/m^3
    # (Engineering ToolBox, "Polyethylene - HDPE"; PPI Handbook of PE Pipe, ch. 3); 20 C
    "HDPE": Material(E=0.9e9, density=950.0, source="Engineering ToolBox; PPI Handbook of PE Pipe"),
}

#: conveyed fluids
FLUIDS: dict[str, Fluid] = {
    # pure water at 20 C, 1 atm: 998.2 kg/m^3 (CRC Handbook, "Properties of Water in the
    # Range 0-100 C"; Engineering ToolBox, "Water - Density")
    "water": Fluid(density=998.0, source="CRC Handbook, 20 C"),
    # sea water, salinity 35 g/kg, about 15 C at the surface: 1025 kg/m^3 (UNESCO
    # equation of state; Engineering ToolBox, "Sea Water Properties")
    "sea water": Fluid(density=1025.0, source="Engineering ToolBox, sea water, 15 C"),
    # dry air at STP as IUPAC defines it (0 C, 100 kPa): 1.275 kg/m^3 (ideal gas,
    # p / (R_specific T) = 1e5 / (287.05 * 273.15); Engineering ToolBox, "Air - Density,
    # Specific Weight and Thermal Expansion Coefficient"); at 0 C and 1 atm it is 1.292
    "air": Fluid(density=1.275, source="Engineering ToolBox, dry air, 0 C, 100 kPa"),
    # a typical mineral (hydraulic or lube) oil, ISO VG 32-68: 870 kg/m^3 at 15 C
    # (Engineering ToolBox, "Liquids - Densities": mineral oils 850-900)
    "oil": Fluid(density=870.0, source="Engineering ToolBox, mineral oil, 15 C"),
}


@dataclass(frozen=True)
class Section:
    """A circular tube's section: outer diameter D and inner diameter d [m] given, its
    second moment of area ``I`` = pi (D^4 - d^4) / 64 [m^4], its wall area
    ``wall_area`` = pi (D^2 - d^2) / 4 [m^2] and its flow (bore) area
    ``flow_area`` = pi d^2 / 4 [m^2]."""

    outer_diameter: float
    inner_diameter: float

    @property
    def I(self) -> float:  # noqa: E743 (the beam theory's name)
        D, d = self.outer_diameter, self.inner_diameter
        return math.pi * (D**4 - d**4) / 64.0

    @property
    def wall_area(self) -> float:
        D, d = self.outer_diameter, self.inner_diameter
        return math.pi * (D**2 - d**2) / 4.0

    @property
    def flow_area(self) -> float:
        return math.pi * self.inner_diameter**2 / 4.0
