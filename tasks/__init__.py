"""The participant's tasks: primary navigation and its scoring, secondary arithmetic,
the contextual task types and the scripted skills that perform them.

Sees only sim's plain types (observations, scene geometry).
"""
