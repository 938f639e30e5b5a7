function msd_linear(Mass, Damping, Stiffness)
%MSD_LINEAR  Mass-spring-damper free response with nested functions.
%   Parameters are shared with the nested right-hand side.

 if nargin < 1
   Mass = 2;        % [kg]
   Damping = 1.2;   % [N s/m]
   Stiffness = 18;  % [N/m]
 end
 tspan = [0 8];
 x0 = [0.1; 0];
 options = odeset('RelTol', 1e-6, 'AbsTol', 1e-8);
 [t, x] = ode45(@msd, tspan, x0, options);
 plot(t, x(:,1))
 title(['m = ' num2str(Mass)])

  function dxdt = msd(t, x)
    % the parent's Mass, Damping and Stiffness
    dxdt = [x(2); -(Damping*x(2) + Stiffness*x(1))/Mass];
  end
end
