"""dynamics: the mode-III spectral boundary-integral code — FFTs, the convolution kernel and its
histories, the predictor-corrector stepper with the friction solve, run configs and run files."""
from .sbi import make_history  # noqa: F401
from .stepper import PredictorCorrector, RateStateInterface, TimeStepRule, make_stepper  # noqa: F401
from .config import build_stepper, load_config  # noqa: F401
from .runfile import RunFile, read_checkpoint  # noqa: F401
