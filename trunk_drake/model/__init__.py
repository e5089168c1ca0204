"""The trunk model: ModelSpec (plain data), the Drake plant, and muscle path kinematics."""
