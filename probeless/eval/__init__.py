"""``probeless eval <name>``: the evaluations against ground truth, one front-end module each.

The top layer beside :mod:`probeless.cli` and :mod:`probeless.bench`: it may import the algorithm
packages, which never import it (nor does it import ``probeless.nodes``). The shared part, the
registry :data:`EVALUATIONS` included, is :mod:`probeless.eval.harness`.
"""

from probeless.eval.harness import EVALUATIONS, add_eval_parser, add_evaluation, add_old_spellings

__all__ = ["EVALUATIONS", "add_eval_parser", "add_evaluation", "add_old_spellings"]
