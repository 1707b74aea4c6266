"""The top-view video writes real MPEG-4 frames that show the run."""
import cv2
import numpy as np

from sparse_nav.sim.world import load_world
from sparse_nav.video import TopViewVideo


def test_video_frames_are_written_and_show_the_track(tmp_path):
    world = load_world("one_room")
    path = str(tmp_path / "run.mp4")
    video = TopViewVideo(path, world, fps=5.0)
    track = [(3.0, 2.5)]
    for i in range(10):
        track.append((3.0 + 0.2 * i, 2.5 + 0.1 * i))
        image = video.add_frame(grid_cells_xy=(np.array([[3.0, 2.5]]), np.array([[0.0, 2.0]])),
                                true_track=track, estimated_track=[(x + 0.1, y) for x, y in track],
                                path=[(3.0, 2.5), (5.5, 5.8)], exit_found=(5.4, 5.7),
                                text=f"t = {i} s")
    video.close()
    assert video.frames == 10
    # The robot's dot (blue in BGR) is drawn where the track ends.
    u, v = video._px(track[-1])[0]
    assert tuple(image[v, u]) == (200, 80, 0)
    capture = cv2.VideoCapture(path)
    assert capture.get(cv2.CAP_PROP_FRAME_COUNT) == 10
    ok, frame = capture.read()
    assert ok and frame.shape[:2] == (video.size[1], video.size[0])
    assert frame.min() < 50  # walls are drawn dark on white
