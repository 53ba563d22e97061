"""``vision-cal design``: the plans a robot draws on the printed sheet (pilot, informative)."""
