function varargout = chem(t,y,flag,k1,k2,k3)
% CHEM  Robertson's chemical kinetics as an ODE file (stiff)
switch flag
case ''
  varargout{1} = f(t,y,k1,k2,k3);
case 'init'
  [varargout{1:3}] = init(k1,k2,k3);
otherwise
  error(['Unknown flag ''' flag '''.']);
end
% ------------------------------------------------------------------
function dydt = f(t,y,k1,k2,k3)
dydt = [ -k1*y(1) + k3*y(2)*y(3)
          k1*y(1) - k3*y(2)*y(3) - k2*y(2)^2
          k2*y(2)^2 ];
% ------------------------------------------------------------------
function [tspan,y0,options] = init(k1,k2,k3)
tspan = [0 40];
y0 = [1; 0; 0];
options = odeset('RelTol',1e-4,'AbsTol',[1e-6 1e-10 1e-6]);
