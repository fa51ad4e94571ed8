"""Barrier contact between MPM particles and FEM boundaries (and between FEM bodies), with
lagged friction: BFEMP paper sections 4-5."""

from bfemp.contact.parameters import ContactParameters

__all__ = ["ContactParameters"]
