"""A UR arm's kinematics as Denavit-Hartenberg tables: UR's nominal tables and the calibrated
table a controller reports (``dh``), the Pinocchio model built from a table
(``pinocchio_dh``), and the file a calibrated model is saved in for offline use
(``model_file``). Nothing here talks to an arm; ``drivers.ur.primary`` reads the table.
"""
