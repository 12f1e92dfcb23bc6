"""Questionnaire instruments (NASA-TLX, experience): items, validation, scoring. Pure."""
