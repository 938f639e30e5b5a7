%quick exercise: the pendulum, linearised
clear all
close all
%initial conditions
Y10=0.4; %displacement in radians
Y20=0;  %angular velocity in radians / sec
xspan=[0,5];
Y0=[Y10 Y20];

%constants
p=[9.81 0.7]; %gravity (m/s2) and length (m)
lin = @(x,y,p) [y(2); -p(1)/p(2)*y(1)]
[x,y]=ode45(lin,xspan,Y0,[],p);
figure(1)
plot(x,y)
grid on
xlabel('t');ylabel('y1 and y2');legend('y1','y2')
