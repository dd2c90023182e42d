"""The time-stepping reducer models by name, as the FMU's `model` parameter names them."""

from .dynamic_reducer import DynamicReducer
from .reducer_model import QuasiStaticReducer

MODELS = {QuasiStaticReducer.name: QuasiStaticReducer, DynamicReducer.name: DynamicReducer}
