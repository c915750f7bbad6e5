"""
Sweep files of a study: ``study: forensics`` marks a file that states the replication forensics (its sizes and its
candidate grid) instead of agents x grid x seeds. ``sweep_file.load_sweep_file`` validates it with these models, as
it validates a sweep of runs with ``schema.Sweep``; ``sb3-affect run`` hands it to the forensics, whose replications
run on the launcher's executor (local processes or Ray tasks)::

    name: forensics
    study: forensics
    screen_reps: 2          # replications of every simulation in the screen
    leaders: 4              # affective simulations replicated in full
    reps: 30                # replications of each leader
    alphas: [0.5, 1.0]      # the candidate grid's learning rates
    gammas: [0.7, 0.8, 0.9] # and discounts
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

from sb3_affect.study.launcher.schema import MAX_EPISODES, MAX_SEEDS, NAME_PATTERN

#: Replications of one simulation: the summaries' file names hold 4 digits (``r0000.json`` to ``r9999.json``).
MAX_REPS = 10_000


def _check_range(values: list[float] | None, what: str, low_open: bool) -> None:
    """
    Each value in [0, 1] (``low_open``: in (0, 1]) and given once (a value twice would be one simulation counted as
    two), or a one-line error naming the first that is not.
    """
    for index, value in enumerate(values or []):
        if not (0 < value <= 1 if low_open else 0 <= value <= 1):
            raise ValueError(f"{value!r} is not {what}; each is in {'(0, 1]' if low_open else '[0, 1]'}")
        if value in (values or [])[:index]:
            raise ValueError(f"{value!r} is given twice; give each {what.removeprefix('an ').removeprefix('a ')} once")


class ProtocolSpec(BaseModel):
    """The forensics' ``protocol``: what one replication of a simulation runs (a key left out: the paper's)."""

    model_config = ConfigDict(extra="forbid")
    epsilons: list[float] | None = Field(
        default=None,
        min_length=2,
        description="the ε values, each in [0, 1]; the affective agent runs once per value (null: the paper's 0.1, "
        "0.2, ..., 0.9)",
    )
    seeds: int | None = Field(
        default=None, gt=0, le=MAX_SEEDS, description="simulations per ε and agent (null: the paper's 20)"
    )
    episodes: int | None = Field(
        default=None, gt=0, le=MAX_EPISODES, description="episodes per simulation (null: the paper's 200)"
    )

    @field_validator("epsilons")
    @classmethod
    def _epsilons(cls, value: list[float] | None) -> list[float] | None:
        _check_range(value, "an ε", low_open=False)
        return value


class ForensicsStudy(BaseModel):
    """A sweep file of the replication forensics (top-level keys)."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(pattern=NAME_PATTERN, description="the study's name (letters, digits, _ . + -, at most 64 characters)")
    study: Literal["forensics"] = Field(
        description="marks the file as the replication forensics: which candidate implementation could have printed "
        "the paper's numbers"
    )
    screen_reps: int = Field(
        ge=2, le=MAX_REPS, description="replications of every simulation in the screen (a spread needs two)"
    )
    leaders: int = Field(ge=1, description="affective simulations, best first after the screen, replicated in full")
    reps: int = Field(
        ge=2, le=MAX_REPS, description=f"replications of each leader, at least screen_reps (at most {MAX_REPS:,})"
    )
    alphas: list[float] = Field(min_length=1, description="the learning rates of the candidate grid, each in (0, 1]")
    gammas: list[float] = Field(min_length=1, description="the discounts of the candidate grid, each in [0, 1]")
    protocol: ProtocolSpec = Field(
        default_factory=ProtocolSpec, description="what one replication runs (below; default: the paper's protocol)"
    )

    @field_validator("alphas")
    @classmethod
    def _alphas(cls, value: list[float]) -> list[float]:
        _check_range(value, "a learning rate", low_open=True)
        return value

    @field_validator("gammas")
    @classmethod
    def _gammas(cls, value: list[float]) -> list[float]:
        _check_range(value, "a discount", low_open=False)
        return value

    @field_validator("reps")
    @classmethod
    def _enough_reps(cls, value: int, info: ValidationInfo) -> int:
        screen_reps = info.data.get("screen_reps")
        if screen_reps is not None and value < screen_reps:
            raise ValueError(f"fewer than screen_reps ({screen_reps}); give reps >= {screen_reps}")
        return value
