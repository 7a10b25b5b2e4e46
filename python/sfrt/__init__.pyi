# Type stubs of the sfrt package (the compiled module sfrt._sfrt), for editors and type checkers.
from typing import Any, Iterator, Optional, Tuple

import numpy as np
import numpy.typing as npt

__version__: str

class Error(RuntimeError):
    """A failure of the sfrt library; the message is the C++ library's."""

class Model:
    """A model file (.sfrt), loaded and verified; shared by any number of Sessions."""
    def __init__(self, path: str) -> None: ...
    @property
    def path(self) -> str: ...
    @property
    def info(self) -> dict[str, Any]: ...

class Session:
    """A Model planned for one input size; one per thread."""
    def __init__(
        self,
        model: Model,
        size: Optional[Tuple[int, int]] = None,
        threads: int = 1,
        isa: str = "auto",
        allow_aspect_change: bool = False,
    ) -> None: ...
    def run(
        self,
        left0: npt.NDArray[np.uint8],
        right0: npt.NDArray[np.uint8],
        left1: npt.NDArray[np.uint8],
        right1: npt.NDArray[np.uint8],
        *,
        color: str = "bgr",
        out: Optional[npt.NDArray[np.float32]] = None,
    ) -> npt.NDArray[np.float32]: ...
    def run_rgbd(
        self,
        color0: npt.NDArray[np.uint8],
        depth0: npt.NDArray[Any],
        color1: npt.NDArray[np.uint8],
        depth1: npt.NDArray[Any],
        *,
        depth_units: float = 1000.0,
        color: str = "bgr",
        out: Optional[npt.NDArray[np.float32]] = None,
    ) -> npt.NDArray[np.float32]: ...
    def run_tensor(
        self, x: npt.NDArray[np.float32], *, out: Optional[npt.NDArray[np.float32]] = None
    ) -> npt.NDArray[np.float32]: ...
    @property
    def size(self) -> Tuple[int, int]: ...
    @property
    def isa(self) -> str: ...
    @property
    def threads(self) -> int: ...
    @property
    def model(self) -> Model: ...
    @property
    def arena_bytes(self) -> int: ...

class Window:
    """One (t, t+1) window of a replay."""
    @property
    def flow(self) -> npt.NDArray[np.float32]: ...
    @property
    def index(self) -> int: ...
    @property
    def t0(self) -> float: ...
    @property
    def t1(self) -> float: ...
    @property
    def sources(self) -> dict[str, Any]: ...
    @property
    def name(self) -> str: ...

class Replay(Iterator[Window]):
    """The windows of a replay (sfrt.replay)."""
    def __iter__(self) -> "Replay": ...
    def __next__(self) -> Window: ...
    def close(self) -> None: ...
    def __enter__(self) -> "Replay": ...
    def __exit__(self, *args: Any) -> None: ...
    @property
    def summary(self) -> Optional[dict[str, Any]]: ...
    @property
    def warnings(self) -> list[str]: ...

def replay(
    model: Model,
    *,
    left: str = "",
    right: str = "",
    dataset: str = "",
    video: str = "",
    bag: str = "",
    left_topic: str = "left/image_rect",
    right_topic: str = "right/image_rect",
    size: Optional[Tuple[int, int]] = None,
    threads: int = 1,
    isa: str = "auto",
    max_frames: int = 0,
    rendering_pass: str = "clean",
    on_bad_frame: str = "stop",
) -> Replay: ...

def evaluate(
    model: Optional[Model],
    dataset: str,
    *,
    size: Optional[Tuple[int, int]] = None,
    max_frames: int = 0,
    classical: bool = True,
    thresholds: str = "absolute",
    allow_camera_mismatch: bool = False,
    isa: str = "auto",
    depth: str = "gt",
    write_submission: str = "",
) -> dict[str, Any]: ...
