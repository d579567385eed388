"""dynamics: the mode-III spectral boundary-integral code — FFTs, the convolution kernel and its
histories, the predictor-corrector stepper with the friction solve, run configs and run files."""
from .sbi import make_history
from .stepper import PredictorCorrector, RateStateInterface, TimeStepRule, make_stepper
from .config import build_stepper, load_config
from .runfile import RunFile, read_checkpoint

__all__ = ['make_history', 'PredictorCorrector', 'RateStateInterface', 'TimeStepRule',
           'make_stepper', 'build_stepper', 'load_config', 'RunFile', 'read_checkpoint']
