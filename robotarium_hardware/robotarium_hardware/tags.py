"""ArUco tags over the arena, without ROS: an overhead camera's model and images (the camera stand-in),
and finding the robots' poses in such an image (the tag tracker). OpenCV and numpy.

The tracker needs nothing of the camera: the four corner tags (ids `corner_tags`, their centres at the
arena's corners (x_min, y_min), (x_max, y_min), (x_max, y_max), (x_min, y_max)) give the homography from
the image to the floor, so a camera anywhere above the arena, tilted or not, with any lens that is close
to a pinhole, gives poses in the arena's frame. A robot's tag lies flat on it, centred on its axle, the
top edge of the marker towards the robot's front: its centre is the robot's position, the direction from
the middle of its bottom edge to the middle of its top edge the robot's heading.

Markers: DICT_4X4_50, drawn with cv2.aruco.generateImageMarker; each printed with a white margin of one
cell (the quiet zone the detector needs).
"""
import dataclasses
import math

import cv2
import numpy as np

DICTIONARY = cv2.aruco.DICT_4X4_50
CELLS = 6            # a 4x4 marker with its black border is 6 cells wide
MARKER_PIXELS = 60   # the marker images drawn (10 pixels a cell), before they are warped into a frame
NOISE_SHIFT = 128    # pixels: the sensor noise of a frame is a window this far at most into a larger field


def dictionary():
    return cv2.aruco.getPredefinedDictionary(DICTIONARY)


def detector():
    """An ArucoDetector for DICT_4X4_50 with sub-pixel corners (the poses come from the corners). One
    adaptive-threshold window of 7 pixels instead of OpenCV's three (3, 13, 23): tags of 25-40 pixels
    are all found with it, in a third of the time (7 ms instead of 20 for a 1280 x 800 frame, here)."""
    parameters = cv2.aruco.DetectorParameters()
    parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    parameters.adaptiveThreshWinSizeMin = parameters.adaptiveThreshWinSizeMax = 7
    parameters.minMarkerPerimeterRate = 0.05
    return cv2.aruco.ArucoDetector(dictionary(), parameters)


def marker_image(tag, margin_cells=1):
    """The marker `tag` with a white margin, as a square uint8 image."""
    marker = cv2.aruco.generateImageMarker(dictionary(), int(tag), MARKER_PIXELS)
    pad = int(round(margin_cells * MARKER_PIXELS / CELLS))
    return cv2.copyMakeBorder(marker, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=255)


def square(x, y, theta, size):
    """4 x 2 floor points of a tag of side `size` centred at (x, y), its top edge towards heading theta:
    top-left, top-right, bottom-right, bottom-left of the marker image (the detector's corner order)."""
    c, s, h = math.cos(theta), math.sin(theta), size / 2
    local = np.array([[h, h], [h, -h], [-h, -h], [-h, h]])   # (forward, left) of each corner
    return np.array([x, y]) + local @ np.array([[c, s], [-s, c]])


def corner_positions(arena):
    x_min, x_max, y_min, y_max = arena
    return np.array([[x_min, y_min], [x_max, y_min], [x_max, y_max], [x_min, y_max]])


@dataclasses.dataclass(frozen=True)
class OverheadCamera:
    """A pinhole camera above the arena's centre, looking down, tilted `tilt` rad about the image's
    horizontal axis (so the floor is seen in perspective), its image `width` x `height` pixels, mono8.
    project(): floor points -> pixels."""
    width: int = 1280
    height: int = 800
    focal: float = 880.0      # pixels: the arena and its corner tags fill the frame
    altitude: float = 2.6     # m above the floor
    tilt: float = 0.08        # rad
    centre: tuple = (0.0, 0.0)

    def rotation(self):
        # world -> camera for a camera looking straight down (image x = world x, image y = -world y), then tilted
        down = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
        c, s = math.cos(self.tilt), math.sin(self.tilt)
        return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]) @ down

    def project(self, points):
        """N x 2 floor points (z = 0) -> N x 2 pixels."""
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        # the camera stands above the centre, shifted so that the tilted view is still centred on the arena
        position = np.array([self.centre[0], self.centre[1] + self.altitude * math.tan(self.tilt), self.altitude])
        world = np.column_stack([points, np.zeros(len(points))]) - position
        camera = world @ self.rotation().T
        return np.column_stack([self.focal * camera[:, 0] / camera[:, 2] + self.width / 2,
                                self.focal * camera[:, 1] / camera[:, 2] + self.height / 2])


class Renderer:
    """Images of the arena as the overhead camera sees it: a grey floor with the arena's edge, each robot
    a dark disc wearing its tag, the four corner tags; blurred and with sensor noise."""

    def __init__(self, camera, arena, corner_tags, corner_tag_size, tag_size, robot_diameter=0.11, blur=0.8,
                 noise=3.0, seed=1):
        self.camera, self.arena = camera, arena
        self.tag_size, self.robot_radius = tag_size, robot_diameter / 2
        self.blur, self.noise = blur, noise
        self.rng = np.random.default_rng(seed)
        self.markers = {}
        self.background = np.full((camera.height, camera.width), 150, np.uint8)
        edge = camera.project(corner_positions(arena)).round().astype(np.int32)
        cv2.polylines(self.background, [edge], True, 110, 2, cv2.LINE_AA)
        for tag, (x, y) in zip(corner_tags, corner_positions(arena)):
            self._paste(self.background, tag, square(x, y, 0.0, corner_tag_size))
        # Sensor noise: a window at a random offset into one larger field drawn once (16 384 different frames of
        # it), not a field drawn each frame: drawing a 1280 x 800 field took 3 ms of the 7.5 a frame took here.
        self._noise = np.rint(self.rng.normal(0.0, noise, (camera.height + NOISE_SHIFT, camera.width + NOISE_SHIFT)))
        self._noise = self._noise.astype(np.int16)

    def _marker(self, tag):
        if tag not in self.markers:
            self.markers[tag] = marker_image(tag)
        return self.markers[tag]

    def _paste(self, image, tag, corners, card=False):
        """Warp the marker (with its margin) onto the floor quadrilateral `corners` (the marker's own
        square; the margin goes around it), within its bounding box only; card=True: the white card it is
        printed on (the marker with its margin, all white)."""
        marker = self._marker(tag)
        m = marker.shape[0]
        centre = corners.mean(axis=0)
        outer = centre + (corners - centre) * (m / MARKER_PIXELS)   # the margin's corners on the floor
        pixels = self.camera.project(outer).astype(np.float32)
        x0, y0 = np.floor(pixels.min(axis=0)).astype(int) - 1
        x1, y1 = np.ceil(pixels.max(axis=0)).astype(int) + 2
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, image.shape[1]), min(y1, image.shape[0])
        if x1 <= x0 or y1 <= y0:
            return
        source = np.float32([[0, 0], [m - 1, 0], [m - 1, m - 1], [0, m - 1]])
        homography = cv2.getPerspectiveTransform(source, pixels - np.float32([x0, y0]))
        size = (x1 - x0, y1 - y0)
        mask = cv2.warpPerspective(np.full_like(marker, 255), homography, size, flags=cv2.INTER_LINEAR)
        warped = mask if card else cv2.warpPerspective(marker, homography, size, flags=cv2.INTER_LINEAR)   # (a card is all white)
        roi = image[y0:y1, x0:x1]
        alpha = mask.astype(np.float32) / 255.0
        roi[:] = (roi * (1 - alpha) + warped * alpha).astype(np.uint8)

    def render(self, poses, tags, hidden=()):
        """The image of robots at `poses` (3 x N, arena frame) wearing `tags` (N ids); robots whose index is
        in `hidden` show no tag (a hand over it)."""
        image = self.background.copy()
        for x, y, _ in poses.T:   # the bodies first, then the tags on top of them (a tag's corners reach past its
            rim = self.camera.project(np.array([[x, y], [x + self.robot_radius, y]]))   # body over a neighbour's)
            radius = int(round(np.hypot(*(rim[1] - rim[0]))))
            cv2.circle(image, tuple(int(round(v)) for v in rim[0]), radius, 40, -1, cv2.LINE_AA)
        # Then the cards the tags are printed on, then the tags: a card's white margin reaches past its robot's
        # body, and drawn over a neighbour's tag it cut that tag's corner off (two robots 11 cm apart, a still
        # one unreadable frame after frame). On the floor a card lies on its own robot, never over another's tag.
        shown = [(tags[k], square(x, y, theta, self.tag_size)) for k, (x, y, theta) in enumerate(poses.T)
                 if k not in hidden]
        for tag, corners in shown:
            self._paste(image, tag, corners, card=True)
        for tag, corners in shown:
            self._paste(image, tag, corners)
        if self.blur:
            image = cv2.GaussianBlur(image, (0, 0), self.blur)
        if self.noise:
            dy, dx = self.rng.integers(0, NOISE_SHIFT, 2)
            image = cv2.add(image, self._noise[dy:dy + image.shape[0], dx:dx + image.shape[1]], dtype=cv2.CV_8U)
        return image


class TagTracker:
    """Robot poses from an image: the corner tags give the image -> floor homography (kept from the last
    image that showed all four, so a corner hidden for a moment costs nothing), each robot's tag its pose.
    `tags`: {tag id: robot index}."""

    RETRY = 40          # pixels around a missing tag's last place that a second, slower detector looks at
    RETRY_FRAMES = 30   # frames (a second at 30 Hz) it looks there again, each frame, while the tag stays missing

    def __init__(self, arena, corner_tags, tags):
        self.detector = detector()
        parameters = cv2.aruco.DetectorParameters()   # OpenCV's own: three threshold windows (3, 13, 23)
        parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        self.thorough = cv2.aruco.ArucoDetector(dictionary(), parameters)
        self.corner_tags = list(corner_tags)
        self.corners = corner_positions(arena).astype(np.float32)
        self.tags = dict(tags)
        self.homography = None
        self.last = {}   # tag -> (its corners' pixels where it was last found, frames missing since)
        self.retries = self.recovered = 0

    def track(self, image):
        """{robot index: (x, y, theta)} of the robots whose tag is in `image` (none before the corner tags
        were seen once)."""
        found, ids, _ = self.detector.detectMarkers(image)
        by_id = {} if ids is None else {int(i): c.reshape(4, 2) for i, c in zip(ids.ravel(), found)}
        # A robot's tag found lately and missing now: OpenCV's slower detector looks again around its last place
        # (a tag that noise and JPEG, or a neighbour's tag close by, made unreadable to one threshold window is
        # read by another), every frame while it stays missing, not only the first: a robot standing still stays
        # as hard to read frame after frame. A tag that is really hidden stays missing at the cost of a small crop.
        for tag, (corners, _) in self.last.items():
            if tag not in by_id:
                self.retries += 1
                x0, y0 = np.maximum(corners.min(axis=0).astype(int) - self.RETRY, 0)
                x1, y1 = corners.max(axis=0).astype(int) + self.RETRY
                crop = np.ascontiguousarray(image[y0:y1, x0:x1])
                again, again_ids, _ = self.thorough.detectMarkers(crop)
                for i, c in zip(() if again_ids is None else again_ids.ravel(), again):
                    if int(i) == tag:
                        by_id[tag] = c.reshape(4, 2) + np.float32([x0, y0])
                        self.recovered += 1
        self.last = {t: (by_id[t], 0) if t in by_id else (corners, missing + 1)
                     for t, (corners, missing) in self.last.items() if t in by_id or missing + 1 < self.RETRY_FRAMES}
        self.last.update((t, (c, 0)) for t, c in by_id.items() if t in self.tags)
        if not by_id:
            return {}
        if all(t in by_id for t in self.corner_tags):
            centres = np.float32([by_id[t].mean(axis=0) for t in self.corner_tags])
            self.homography = cv2.getPerspectiveTransform(centres, self.corners)
        if self.homography is None:
            return {}
        poses = {}
        for tag, robot in self.tags.items():
            if tag in by_id:
                floor = cv2.perspectiveTransform(by_id[tag].reshape(1, 4, 2).astype(np.float32), self.homography)[0]
                front, back = (floor[0] + floor[1]) / 2, (floor[3] + floor[2]) / 2
                x, y = floor.mean(axis=0)
                poses[robot] = (float(x), float(y), math.atan2(front[1] - back[1], front[0] - back[0]))
        return poses


# -- sensor_msgs/Image and CompressedImage as bytes (a frame 30 times a second: no message object) --------

def _string(text):
    raw = text.encode() + b"\0"
    return len(raw).to_bytes(4, "little") + raw


def _align(buffer, n):
    buffer.extend(b"\0" * ((-(len(buffer) - 4)) % n))


def image_bytes(sec, nanosec, frame_id, gray):
    """The CDR bytes of a sensor_msgs/Image (mono8) of the 2-D uint8 array `gray`."""
    height, width = gray.shape
    buffer = bytearray(b"\x00\x01\x00\x00")
    buffer += int(sec).to_bytes(4, "little", signed=True) + int(nanosec).to_bytes(4, "little")
    buffer += _string(frame_id)
    _align(buffer, 4)
    buffer += height.to_bytes(4, "little") + width.to_bytes(4, "little") + _string("mono8")
    buffer += b"\0"   # is_bigendian
    _align(buffer, 4)
    buffer += width.to_bytes(4, "little") + (height * width).to_bytes(4, "little")
    return bytes(buffer) + np.ascontiguousarray(gray, dtype=np.uint8).tobytes()


def parse_image(data):
    """(stamp in s, 2-D uint8 array) of a serialized sensor_msgs/Image in mono8 or bgr8/rgb8 (then grey);
    ValueError for anything else."""
    view = memoryview(data)

    def uint(offset):
        return int.from_bytes(view[offset:offset + 4], "little")

    def string(offset):
        length = uint(offset)
        if length > 256:
            raise ValueError("a string of %d bytes in an Image" % length)
        return bytes(view[offset + 4:offset + 3 + length]).decode(errors="replace"), offset + 4 + length

    def aligned(offset, n):
        return offset + (-(offset - 4)) % n
    if len(data) < 32 or data[1] != 1:
        raise ValueError("not a little-endian CDR Image")
    stamp = int.from_bytes(view[4:8], "little", signed=True) + uint(8) * 1e-9
    _, offset = string(12)
    offset = aligned(offset, 4)
    height, width = uint(offset), uint(offset + 4)
    encoding, offset = string(offset + 8)
    offset = aligned(offset + 1, 4)
    step, size = uint(offset), uint(offset + 4)
    pixels = np.frombuffer(view[offset + 8:offset + 8 + size], dtype=np.uint8)
    if encoding == "mono8" and size == height * step and step >= width:
        return stamp, pixels.reshape(height, step)[:, :width]
    if encoding in ("bgr8", "rgb8") and size == height * step and step >= 3 * width:
        colour = pixels.reshape(height, step)[:, :3 * width].reshape(height, width, 3)
        return stamp, cv2.cvtColor(colour, cv2.COLOR_BGR2GRAY if encoding == "bgr8" else cv2.COLOR_RGB2GRAY)
    raise ValueError("an Image of %dx%d %s (%d bytes); mono8, bgr8 or rgb8 is needed" % (width, height, encoding, size))


JPEG_QUALITY = 85   # a 1280 x 800 frame in about 100 kB (2 ms to encode, 3 to decode here)


def compressed_bytes(sec, nanosec, frame_id, gray, quality=JPEG_QUALITY):
    """The CDR bytes of a sensor_msgs/CompressedImage (format "jpeg", as image_transport's compressed
    plugin publishes it) of the 2-D uint8 array `gray`."""
    ok, encoded = cv2.imencode(".jpg", gray, [cv2.IMWRITE_JPEG_QUALITY, quality])
    buffer = bytearray(b"\x00\x01\x00\x00")
    buffer += int(sec).to_bytes(4, "little", signed=True) + int(nanosec).to_bytes(4, "little")
    buffer += _string(frame_id)
    _align(buffer, 4)
    buffer += _string("jpeg")
    _align(buffer, 4)
    buffer += len(encoded).to_bytes(4, "little")
    return bytes(buffer) + encoded.tobytes()


def parse_compressed(data):
    """(stamp in s, 2-D uint8 array) of a serialized sensor_msgs/CompressedImage (jpeg or png);
    ValueError for anything else."""
    view = memoryview(data)
    if len(data) < 24 or data[1] != 1:
        raise ValueError("not a little-endian CDR CompressedImage")
    stamp = int.from_bytes(view[4:8], "little", signed=True) + int.from_bytes(view[8:12], "little") * 1e-9
    offset = 12
    for _ in range(2):   # frame_id, then format
        length = int.from_bytes(view[offset:offset + 4], "little")
        if length > 256:
            raise ValueError("a string of %d bytes in a CompressedImage" % length)
        offset += 4 + length
        offset += (-(offset - 4)) % 4
    size = int.from_bytes(view[offset:offset + 4], "little")
    encoded = np.frombuffer(view[offset + 4:offset + 4 + size], dtype=np.uint8)
    gray = cv2.imdecode(encoded, cv2.IMREAD_GRAYSCALE) if size else None
    if gray is None:
        raise ValueError("a CompressedImage that does not decode (%d bytes)" % size)
    return stamp, gray
