"""Activity classifier: the seed's multiperspective DCNN (Sect. VII), its preprocessing, training and metrics."""
from processing.classifier.metrics import Report, classification_report, confusion_matrix
from processing.classifier.model import ModelConfig, MultiPerspectiveDCNN, build_model
from processing.classifier.preprocess import PreprocessConfig, preprocess, preprocess_links
from processing.classifier.predictor import Classifier
from processing.classifier.training import (TrainConfig, TrainResult, load_checkpoint, save_checkpoint,
                                         split_indices, train)

__all__ = ["Classifier", "ModelConfig", "MultiPerspectiveDCNN", "PreprocessConfig", "Report", "TrainConfig",
           "TrainResult", "build_model", "classification_report", "confusion_matrix", "load_checkpoint",
           "preprocess", "preprocess_links", "save_checkpoint", "split_indices", "train"]
