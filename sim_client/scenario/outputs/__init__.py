"""What a scenario run leaves behind besides its report, in the run's folder.

- ``recording.mcap`` (:mod:`.recording`): every topic, serialized CDR with ROS 2 message definitions;
- ``video.mp4`` (:mod:`.render`, :mod:`.framing`, :mod:`.overlay`): the run re-rendered offscreen from the
  recorded state;
- ``*.png`` (:mod:`.plots`, :mod:`.camera_sheet`): plots of the path, the speeds and the quantities the
  expectations check; the robot's camera frames on one sheet.

:mod:`.goalview` says what the pictures show of each goal.
"""
