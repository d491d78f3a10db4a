"""Actuator models shared by every robot and bench rig: each runs natively in MuJoCo, driven through ``ctrl`` only.

- :mod:`envs.actuators.dcmotor`: MuJoCo's ``dcmotor`` driven by voltage (a PWM duty cycle) or by an on-board PID
  (a firmware's position controller); the VelociRoACH's motors.
- :mod:`envs.actuators.motor`: the xJüs report's DC gearmotor [xjus-report, Table 1], duty held over a control step.
- :mod:`envs.actuators.battery`: a battery whose terminal voltage sags with the power drawn (its internal
  resistance); the VelociRoACH's cell.
- :mod:`envs.actuators.servo`: the Dynamixel AX-12 servo: a DC motor behind a 254:1 gearbox under its own position
  controller.
"""
