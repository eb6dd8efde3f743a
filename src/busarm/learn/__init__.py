"""Learning from demonstration: busarm's robot and twin for LeRobot (docs/lerobot.md).

``record`` (the expert's episodes on seeded twin tables, many side by side) and ``human``
(a person's, from a leader arm, the keyboard or the dashboard) write LeRobotDatasets
through LeRobot's own API (``dataset``); ``env`` is the twin as a gymnasium environment,
its success judged on the twin's truth; ``frames`` drives any busarm robot one frame at a
time with every action clipped to the limits (``limits``); ``policy`` and ``rollout`` let
a trained LeRobot policy drive it. LeRobot and PyTorch are not busarm's dependencies:
``make lerobot`` makes an environment with them."""

__all__: list[str] = []
