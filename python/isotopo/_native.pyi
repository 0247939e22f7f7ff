# Type stubs of the native module (crates/isotopo-py). Use the package's functions instead:
# they check the arguments and wrap the JSON reports these return.
from os import PathLike
from typing import Any, Callable, Dict, Optional, Sequence, Tuple, Union

import numpy as np

__version__: str

_Progress = Optional[Callable[[str, int, int], Any]]

class Header:
    """A file's header, kept by isotopo.load for isotopo.save(..., like=...)."""

    @property
    def path(self) -> str: ...
    @property
    def format(self) -> str: ...
    @property
    def dtype(self) -> str: ...
    @property
    def dims(self) -> Tuple[int, int, int]: ...
    @property
    def affine(self) -> Sequence[Sequence[float]]: ...
    @property
    def spacing(self) -> Tuple[float, float, float]: ...
    @property
    def scaling(self) -> Tuple[float, float]: ...

def genus(volume: np.ndarray, opts: Dict[str, Any], progress: _Progress = None) -> str: ...
def analyze(volume: np.ndarray, opts: Dict[str, Any], progress: _Progress = None) -> str: ...
def simplify(
    volume: np.ndarray, out: np.ndarray, opts: Dict[str, Any], progress: _Progress = None
) -> str: ...
def load(
    path: Union[str, PathLike[str]], raw: Optional[Dict[str, Any]] = None
) -> Tuple[np.ndarray, Header]: ...
def save(
    path: Union[str, PathLike[str]],
    array: np.ndarray,
    like: Optional[Header] = None,
    affine: Optional[Sequence[Sequence[float]]] = None,
) -> None: ...
