"""The exit finder's room outline of each SLAM map, for the conductor's rules (ROS-free)."""


class OutlinesByMap:
    """The last room outline the exit finder drew in each SLAM map (by map index).

    An outline holds in the frame of the map it was drawn in: tracking back in that map (SLAM
    merging back into it, or relocalising in it) brings it back, and a map begun since has none.
    An answer without a room (too few points, no room shape) keeps the map's last outline: the
    room is still there, and the rules that measure against it need one.
    """

    def __init__(self):
        self._by_map = {}

    def answered(self, map_index, outline):
        """The finder's answer in map_index drew outline (pairs of x, y; empty: no room);
        returns the outline that now holds there."""
        outline = tuple(tuple(map(float, p)) for p in outline)
        if len(outline) >= 3:
            self._by_map[map_index] = outline
        return self.get(map_index)

    def get(self, map_index):
        """The outline of map_index, () when the finder drew none there."""
        return self._by_map.get(map_index, ())
