"""Which dot is which mark: the stage between measure/ (photos -> dots in sheet millimetres)
and estimate/ (marks -> the robot model).

Modules: ``associate`` (dots grouped across photos, matched to the plan through the robot
model), ``infer`` (which marks each photo shows, when session.json does not list them),
``plan_match`` (photos that do not match the plan stop the run), ``match`` (the stage: the
association, predicted with the robot file's tool and again with the tool's first guess),
``marks`` (each mark combined over its photos, the sheet's height). It imports measure/,
dataset/, model/ and the root's config and errors, nothing above it
(tests/test_architecture.py).
"""
