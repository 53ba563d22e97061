"""The synthetic world: a robot of its own with hidden effects draws on a sheet and is
photographed, written as a dataset in the format's files (``docs/format.md``).

    scene.py (scene files) -> truth_model.py (the true robot, every effect written out from
    the contract) -> drawing.py (where the pen marks land; simulate.py runs the plan through
    controller.py and dynamics.py: trajectory, sliding-mode or PD tracking, gear play) ->
    sheet.py, printed.py, print_deviation.py, height.py (the sheet as printed and lying) ->
    camera.py, photo.py (pyrender and the lens) -> dataset.py (the folder and truth.json)

beside it the arm's camera (arm_camera.py) and the rehearsal of a robot program
(rehearse.py). The worlds only tests and benches use (pose pairs, a six-axis arm, a sheet
on a table seen by two cameras) are built on this one in the repository's ``worlds/``,
not installed. It imports nothing that estimates (``tests/test_architecture.py``): a
convention error there would cancel between the data and the fit."""
