"""Classification metrics (accuracy, macro-F1, confusion matrix) against hand-computed values."""

import numpy as np
import pytest

from wearnav.errors import ValidationError
from wearnav.metrics import accuracy, confusion_matrix, macro_f1


def test_confusion_accuracy_f1_by_hand():
    t = [0, 0, 0, 1, 1, 2]
    p = [0, 0, 1, 1, 2, 2]
    c = confusion_matrix(t, p, 3)
    assert c.tolist() == [[2, 1, 0], [0, 1, 1], [0, 0, 1]]
    assert accuracy(t, p, 3) == pytest.approx(4 / 6)
    # F1 per class: 2TP/(2TP+FP+FN): class 0: 4/5, class 1: 2/4, class 2: 2/3
    assert macro_f1(t, p, 3) == pytest.approx(np.mean([4 / 5, 2 / 4, 2 / 3]))


def test_perfect_and_absent_classes():
    t = np.array([1, 1, 3])
    assert accuracy(t, t, 5) == 1.0
    assert macro_f1(t, t, 5) == 1.0  # classes 0, 2, 4 never occur: not scored
    # a class predicted but never true scores 0
    assert macro_f1([1, 1], [1, 0], 2) == pytest.approx(np.mean([0.0, 2 / 3]))


def test_bad_labels_refused():
    with pytest.raises(ValidationError):
        accuracy([0, 1], [0], 2)
    with pytest.raises(ValidationError):
        confusion_matrix([0, 3], [0, 1], 3)
    with pytest.raises(ValidationError):
        macro_f1([], [], 2)
