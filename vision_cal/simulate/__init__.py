"""Simulated controller: SCARA dynamics, gear backlash, sliding-mode and PD tracking."""
