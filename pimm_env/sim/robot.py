"""The differential-drive robot (thesis 3.1.3): wheel kinematics, wheel encoders and their odometry.

The robot body moves kinematically: commanded wheel speeds turn the wheels, and each wheel's travel over
the floor is its rotation times its *true* radius, with slip. The true radii and axle differ slightly from
the nominal ones (drawn once per episode), so odometry computed with the nominal values from quantized,
noisy encoder readings drifts the way a real robot's does.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pimm_env.geometry import wrap_angle


@dataclass(frozen=True)
class RobotConfig:
    """Defaults: the thesis's robot (wheel radius 9.4 cm, half axle 16.5 cm, 32 ms control step)."""

    wheel_radius: float = 0.094
    half_axle: float = 0.165
    control_dt: float = 0.032
    substeps: int = 4  # kinematic integration steps per control step
    footprint_radius: float = 0.25  # the body as seen by collision checks (a Pioneer 3-DX is ~0.45 m across)
    max_linear: float = 1.0  # m/s
    max_angular: float = 2.0  # rad/s
    encoder_ticks_per_rev: int = 4096
    encoder_noise: float = 0.001  # rad, Gaussian noise on each encoder reading
    radius_error: float = 0.00015  # relative std of each wheel's true radius, drawn per episode (calibrated)
    axle_error: float = 0.002  # relative std of the true half axle, drawn per episode
    slip: float = 0.02  # relative std of each wheel's travel per substep


def integrate_odometry(
    pose: np.ndarray, d_phi_left: float, d_phi_right: float, r: float, half_axle: float
) -> np.ndarray:
    """One odometry update from wheel angle increments, eqs. 3.1-3.5 of the thesis."""
    d = r / 2 * (d_phi_right + d_phi_left)
    d_theta = r / (2 * half_axle) * (d_phi_right - d_phi_left)
    x, y, theta = pose
    return np.array(
        [x + d * np.cos(theta + d_theta / 2), y + d * np.sin(theta + d_theta / 2), wrap_angle(theta + d_theta)]
    )


@dataclass
class DiffDriveRobot:
    """The robot's true state, its wheels, its encoders and its odometry."""

    config: RobotConfig = field(default_factory=RobotConfig)
    pose: np.ndarray = field(default_factory=lambda: np.zeros(3))  # true (x, y, theta), map frame
    odom: np.ndarray = field(default_factory=lambda: np.zeros(3))  # odometry frame
    wheel_angles: np.ndarray = field(default_factory=lambda: np.zeros(2))  # true (left, right), rad
    ticks: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=np.int64))
    true_radii: np.ndarray = field(default_factory=lambda: np.zeros(2))
    true_half_axle: float = 0.0
    travelled: float = 0.0

    def reset(self, pose: np.ndarray, rng: np.random.Generator) -> None:
        """Place the robot, zero its odometry and draw this episode's wheel geometry errors."""
        c = self.config
        self.pose = np.asarray(pose, dtype=float).copy()
        self.odom = np.zeros(3)
        self.wheel_angles = np.zeros(2)
        self.ticks = np.zeros(2, dtype=np.int64)
        self.true_radii = c.wheel_radius * (1 + c.radius_error * rng.standard_normal(2))
        self.true_half_axle = c.half_axle * (1 + c.axle_error * rng.standard_normal())
        self.travelled = 0.0

    def teleport(self, pose: np.ndarray) -> None:
        """Move the body without touching wheels, encoders or odometry (the kidnapped robot)."""
        self.pose = np.asarray(pose, dtype=float).copy()

    def step(self, linear: float, angular: float, rng: np.random.Generator, blocked) -> bool:
        """Drive one control step at (linear, angular); ``blocked(x, y)`` says if a position collides.

        Returns True if the body was stopped by a collision during the step (its wheels still turned).
        """
        c = self.config
        dt = c.control_dt / c.substeps
        wheel_rates = np.array([linear - angular * c.half_axle, linear + angular * c.half_axle]) / c.wheel_radius
        collided = False
        for _ in range(c.substeps):
            d_phi = wheel_rates * dt
            self.wheel_angles += d_phi
            travel = d_phi * self.true_radii * (1 + c.slip * rng.standard_normal(2))
            d = travel.mean()
            d_theta = (travel[1] - travel[0]) / (2 * self.true_half_axle)
            x, y, theta = self.pose
            nx = x + d * np.cos(theta + d_theta / 2)
            ny = y + d * np.sin(theta + d_theta / 2)
            if blocked(nx, ny):
                collided = True
                nx, ny = x, y
            else:
                self.travelled += abs(d)
            self.pose = np.array([nx, ny, wrap_angle(theta + d_theta)])
        self._read_encoders(rng)
        return collided

    def _read_encoders(self, rng: np.random.Generator) -> None:
        c = self.config
        tick = 2 * np.pi / c.encoder_ticks_per_rev
        reading = self.wheel_angles + c.encoder_noise * rng.standard_normal(2)
        ticks = np.floor(reading / tick).astype(np.int64)
        d_phi = (ticks - self.ticks) * tick
        self.ticks = ticks
        self.odom = integrate_odometry(self.odom, d_phi[0], d_phi[1], c.wheel_radius, c.half_axle)
