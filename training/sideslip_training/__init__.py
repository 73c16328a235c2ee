"""sideslip_training: bags → datasets, LSTM/BiLSTM, PSO, evaluation, export.

Not ROS-bound: reads bags through sideslip_msgs_py. The training pipeline lands with
the offline-training issue."""

__version__ = "0.1.0"
