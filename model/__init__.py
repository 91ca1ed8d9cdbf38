"""fleetpinn model core: hybrid physics-informed recurrent cells, integrators and training.

PyTorch + numpy only; never imports the HTTP layer (`app`).
"""
