"""A sink that keeps a run's block frames, for the block-frame tests."""

import copy


class BlockCapture:
    """Deep copies of a run's block frames (``blocks``), its ``info`` and ``final`` frame;
    an epoch frame fails the test (the simulator sends blocks to a sink with ``block``)."""

    def start(self, info):
        self.info, self.blocks = info, []

    def block(self, frame):
        self.blocks.append(copy.deepcopy(frame))

    def epoch(self, frame):
        raise AssertionError("the simulator sends blocks")

    def finish(self, final):
        self.final = final

    def abort(self):
        pass
